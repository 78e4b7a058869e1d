"""echofield.Engine: the online engine fed sample by sample from Python
gives what the causal replay of `run(..., online=True)` gives."""

import numpy as np
import pytest

import echofield
from conftest import LOOPS


def records_in_time_order(mission):
    """The mission's records in the order `echofield run --online` feeds
    them (tools/src/slam/pipeline.rs, `replay`): before each beam, every
    DVL and attitude sample stamped at or before it, merged by stamp with
    DVL first at equal stamps; after the last beam, the rest."""
    dvl, att, cov = mission.dvl, mission.attitude, mission.dvl_covariance
    nav = [(row[0], 0, i) for i, row in enumerate(dvl)]
    nav += [(row[0], 1, i) for i, row in enumerate(att)]
    # Stable sort by (stamp, DVL before attitude); each stream is in order.
    nav.sort(key=lambda r: (r[0], r[1]))

    def nav_record(kind, i):
        if kind == 0:
            row = dvl[i]
            c = None if np.isnan(cov[i]).any() else cov[i].tolist()
            return ("dvl", (row[0], row[1:4].tolist(), bool(row[4]), c))
        row = att[i]
        rate = None if np.isnan(row[4]) else float(row[4])
        return ("attitude", (row[0], row[1], row[2], row[3], rate))

    beams = mission.beams
    k = 0
    for b, stamp in enumerate(beams["stamp_s"]):
        while k < len(nav) and nav[k][0] <= stamp:
            yield nav_record(nav[k][1], nav[k][2])
            k += 1
        yield (
            "beam",
            (
                stamp,
                beams["angle_rad"][b],
                beams["bin_size_m"][b],
                beams["intensities"][b],
                beams["first_bin_range_m"][b],
            ),
        )
    for stamp, kind, i in nav[k:]:
        yield nav_record(kind, i)


def test_engine_beam_by_beam_equals_the_online_replay(tank):
    batch = echofield.run(tank, config=LOOPS, online=True)
    assert batch.report["loops_accepted"] > 0
    engine = echofield.Engine(config=LOOPS, mounting=tank.mounting, name=tank.name)
    push = {
        "beam": engine.push_beam,
        "dvl": engine.push_dvl,
        "attitude": engine.push_attitude,
    }
    events = []
    for kind, args in records_in_time_order(tank):
        events.extend(push[kind](*args))
    # The last rotation completes when the data ends.
    events.extend(engine.end_of_data())
    assert engine.end_of_data() == []
    assert [e["node_id"] for e in events] == list(range(len(events)))
    assert engine.nodes == len(events)
    np.testing.assert_array_equal(engine.poses[-1], events[-1]["pose"])
    assert events[-1]["poses"].shape == (len(events), 3)
    result = engine.finish(ground_truth=tank.ground_truth)
    # Every node as emitted, and the final estimate, exactly as the replay.
    emitted = np.array([[e["stamp_s"], *e["pose"]] for e in events])
    np.testing.assert_array_equal(emitted, batch.emitted)
    np.testing.assert_array_equal(result.emitted, batch.emitted)
    np.testing.assert_array_equal(result.stamps, batch.stamps)
    np.testing.assert_array_equal(result.poses, batch.poses)
    assert result.report["ate_rmse_m"] == batch.report["ate_rmse_m"]
    assert result.report["loops_accepted"] == batch.report["loops_accepted"]


def test_engine_rejects_records_out_of_order_and_then_closes(tank):
    engine = echofield.Engine(mounting=tank.mounting)
    att = tank.attitude
    engine.push_attitude(*att[1, :4])
    with pytest.raises(echofield.Error, match="attitude sample 1"):
        engine.push_attitude(*att[0, :4])
    with pytest.raises(RuntimeError, match="closed"):
        engine.push_attitude(*att[2, :4])


def test_engine_argument_errors():
    engine = echofield.Engine()
    with pytest.raises(TypeError, match="intensities"):
        engine.push_beam(0.0, 0.0, 0.1, "not bins")
    with pytest.raises(echofield.Error, match="mounting|vehicle_from_sonar|unknown"):
        echofield.Engine(config={"mounting": {"no_such_key": 1}})
