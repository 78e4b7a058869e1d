"""echofield from Python in a notebook's worth of code (run by .ci/run).

Simulates the built-in tank mission (no data needed), runs SLAM on it,
evaluates the result against the ground truth, feeds the same mission to
the online engine sample by sample, and re-optimises a pose graph.
Run it with `python tools/python/examples/quickstart.py [OUTPUT_DIR]`; with
matplotlib installed it also draws OUTPUT_DIR/quickstart.png.
"""

import sys
import tempfile
from pathlib import Path

import numpy as np

import echofield

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp())

# 1. A mission: the 20 m x 14 m tank, two laps (2 minutes), with ground truth.
#    echofield.load_mission("my.mcap") reads a recording instead (MCAP, a
#    rosbag2 folder or a St Pere log folder).
mission = echofield.simulate("tank", seed=1)
print(mission)

# 2. SLAM, as `echofield run`; a config is a dict laid over the defaults
#    (echofield.default_config() lists every key): the tank has only 10
#    rotations, so loops may join rotations 3 apart (default 10). `output`
#    writes every file of `echofield run` (plots, g2o, TUM, report.json,
#    mission.mcap).
config = {"loops": {"min_separation_nodes": 3}}
result = echofield.run(mission, config=config, output=out / "run")
print(result)
print("node poses [x, y, yaw]:", result.poses.shape)
print("ATE", round(result.report["ate_rmse_m"], 3), "m; dead reckoning",
      round(result.report["ate_rmse_dead_reckoning_m"], 3), "m")

# 3. Evaluation as `echofield eval` (stamped poses [t, x, y, yaw]): the
#    nodes against the ground truth at their stamps, and the trajectory at
#    the navigation rate (10 Hz) against every ground-truth sample, each
#    paired with the nearest pose within half a period.
nodes = echofield.evaluate(result.trajectory, result.ground_truth)
dense = echofield.evaluate(result.navigation_rate, mission.ground_truth,
                           max_time_diff=0.05)
print("ATE of the nodes", round(nodes["ate"]["rmse_m"], 3), "m over",
      nodes["ate"]["pairs"], "poses; at the navigation rate",
      round(dense["ate"]["rmse_m"], 3), "m over", dense["ate"]["pairs"])
accepted = result.loops["accepted"]
print("loop closures accepted:", int(accepted.sum()), "of", len(accepted))

# 4. Online: the engine takes samples as a vehicle produces them and emits
#    a node per sonar rotation. Here the mission's records are pushed in
#    time order (navigation samples first at equal stamps).
engine = echofield.Engine(config=config, mounting=mission.mounting, name="tank online")
dvl, attitude, beams = mission.dvl, mission.attitude, mission.beams
records = [(t, 0, i) for i, t in enumerate(dvl[:, 0])]
records += [(t, 1, i) for i, t in enumerate(attitude[:, 0])]
records += [(t, 2, i) for i, t in enumerate(beams["stamp_s"])]
for stamp, kind, i in sorted(records):
    if kind == 0:
        events = engine.push_dvl(stamp, dvl[i, 1:4], bool(dvl[i, 4]))
    elif kind == 1:
        events = engine.push_attitude(*attitude[i, :4])
    else:
        events = engine.push_beam(stamp, beams["angle_rad"][i], beams["bin_size_m"][i],
                                  beams["intensities"][i])
    for event in events:
        x, y, yaw = event["pose"]
        print(f"  node {event['node_id']:2d} at {event['stamp_s']:7.1f} s: "
              f"x {x:6.2f} m, y {y:6.2f} m ({1e3 * event['latency_s']:.0f} ms)")
online = engine.finish(ground_truth=mission.ground_truth)
print("online ATE after finish", round(online.report["ate_rmse_m"], 3), "m")

# 5. The pose graph the run wrote, re-optimised by the backend.
graph = echofield.optimize(out / "run" / "graph.g2o", init="file")
print(graph)
assert np.isfinite(graph.poses).all()

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    sys.exit(0)
aligned = np.array(nodes["ate"]["alignment"])  # [x, y, yaw]: reference_from_estimate
c, s = np.cos(aligned[2]), np.sin(aligned[2])
xy = result.navigation_rate[:, 1:3] @ np.array([[c, s], [-s, c]]) + aligned[:2]
fig, ax = plt.subplots(figsize=(6, 5))
ax.plot(xy[:, 0], xy[:, 1], label="optimised, 10 Hz")
ax.plot(mission.ground_truth[:, 1], mission.ground_truth[:, 2], "k--", label="ground truth")
ax.set_aspect("equal")
ax.set_xlabel("x (m)")
ax.set_ylabel("y (m)")
ax.legend()
fig.savefig(out / "quickstart.png", dpi=100)
print("wrote", out / "quickstart.png")
