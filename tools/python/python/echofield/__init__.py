"""echofield: scan-based pose-graph SLAM for underwater vehicles with a
mechanically scanned imaging sonar (MSIS), a DVL and a heading sensor.

The functions are those of the ``echofield`` command line, with results as
numpy arrays:

- ``load_mission(path)`` / ``simulate("tank", seed=1)``: a ``Mission``;
- ``run(mission, config=None, output=None, online=False)``: the SLAM
  pipeline (``echofield run``), a ``RunResult``;
- ``Engine``: the online engine, fed sample by sample;
- ``optimize(graph)``: a 2D pose graph (``echofield optimize``);
- ``evaluate(estimate, reference)``: ATE and RPE (``echofield eval``);
- ``default_config()``: every configuration key with its default.

Poses are rows ``[x_m, y_m, yaw_rad]``, stamped poses
``[stamp_s, x_m, y_m, yaw_rad]`` (float64). Failures raise
``echofield.Error`` with the message the command line would print (file,
record and field for bad input).
"""

from ._native import (
    Engine,
    Error,
    Mission,
    OptimizeResult,
    RunResult,
    __version__,
    default_config,
    evaluate,
    load_mission,
    optimize,
    run,
    simulate,
)

__all__ = [
    "Engine",
    "Error",
    "Mission",
    "OptimizeResult",
    "RunResult",
    "__version__",
    "default_config",
    "evaluate",
    "load_mission",
    "optimize",
    "run",
    "simulate",
]
