"""Writes two synthetic (estimate, reference) TUM pairs for tools/check_evo.sh:
a drifting dead-reckoning-like estimate of a lawnmower path, and the same
estimate with a few stamps shifted by a few milliseconds (association)."""
import math
import random
import sys

def write(path, rows):
    with open(path, "w") as f:
        for t, x, y, yaw in rows:
            f.write(f"{t:.6f} {x!r} {y!r} 0 0 0 {math.sin(yaw / 2)!r} {math.cos(yaw / 2)!r}\n")

out = sys.argv[1]
rng = random.Random(7)
ref, est = [], []
x = y = yaw = 0.0
ex = ey = eyaw = 0.0
for k in range(600):
    t = 1000.0 + 0.5 * k
    turn = 0.05 if (k // 100) % 2 == 0 else -0.05
    step = 0.4
    yaw += turn if (k % 100) > 80 else 0.0
    x += step * math.cos(yaw)
    y += step * math.sin(yaw)
    eyaw = yaw + 0.002 * k + rng.gauss(0, 0.01)
    ex += 1.02 * step * math.cos(eyaw)
    ey += 1.02 * step * math.sin(eyaw)
    ref.append((t, x, y, yaw))
    est.append((t, ex + 3.0, ey - 2.0, eyaw + 0.4))
write(f"{out}/ref_a.txt", ref)
write(f"{out}/est_a.txt", est)
write(f"{out}/ref_b.txt", ref)
write(f"{out}/est_b.txt", [(t + (0.004 if i % 3 == 0 else 0.0), *rest) for i, (t, *rest) in enumerate(est)])
