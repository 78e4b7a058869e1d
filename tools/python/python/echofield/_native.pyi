"""Type stubs of the native module echofield._native (tools/python/src)."""

import os
import pathlib
from typing import Any, Dict, List, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, "os.PathLike[str]"]
Config = Union[None, Mapping[str, Any], PathLike]
Trajectory = Union[npt.NDArray[np.float64], PathLike]

class Error(Exception):
    """A failure of echofield: bad input data (the message names the file,
    record and field), an invalid configuration, or a failed solve."""

class Mission:
    """A mission in memory: sonar beams, DVL and attitude samples, ground
    truth and the sensor mounting, each stream in time order."""

    @property
    def name(self) -> str: ...
    @property
    def mounting(self) -> Dict[str, Any]:
        """The sensor mounting (the keys of a config's ``[mounting]``)."""
    @property
    def beams(self) -> Dict[str, Any]:
        """``stamp_s``, ``angle_rad``, ``bin_size_m``, ``first_bin_range_m``
        (float64 arrays, one value per beam) and ``intensities`` (a list of
        one uint8 array per beam, nearest bin first)."""
    @property
    def dvl(self) -> npt.NDArray[np.float64]:
        """``(n, 5)``: ``[stamp_s, vx_mps, vy_mps, vz_mps, valid]``, velocity
        over ground in the DVL frame, ``valid`` 1.0 or 0.0."""
    @property
    def dvl_covariance(self) -> npt.NDArray[np.float64]:
        """``(n, 3, 3)`` velocity covariances in (m/s)², NaN where absent."""
    @property
    def attitude(self) -> npt.NDArray[np.float64]:
        """``(n, 5)``: ``[stamp_s, roll_rad, pitch_rad, yaw_rad,
        yaw_rate_radps]`` (rate NaN where absent)."""
    @property
    def ground_truth(self) -> npt.NDArray[np.float64]:
        """``(n, 4)`` stamped poses in the ground truth's frame; ``(0, 4)``
        without ground truth."""
    @property
    def channels(self) -> List[Dict[str, Any]]:
        """Per channel of an MCAP / ROS 2 input: ``topic``, ``schema``,
        ``role`` (None when skipped), ``reason``, ``messages``."""
    @property
    def warnings(self) -> Any:
        """What the reader repaired, as ``report.json`` lists it."""
    def save(self, path: PathLike) -> None:
        """Writes the mission as an echofield MCAP file."""

class RunResult:
    """What a run produced. Poses ``[x_m, y_m, yaw_rad]`` and stamped poses
    ``[stamp_s, x_m, y_m, yaw_rad]`` in the dead-reckoning world frame;
    ground truth in its own frame."""

    mission_name: str
    stamps: npt.NDArray[np.float64]
    """Node stamps (the rotations' central times), ``(n,)``."""
    poses: npt.NDArray[np.float64]
    """Optimised node poses, ``(n, 3)``."""
    trajectory: npt.NDArray[np.float64]
    """Optimised node poses with their stamps, ``(n, 4)``."""
    dead_reckoning_poses: npt.NDArray[np.float64]
    """Dead-reckoning node poses, ``(n, 3)``."""
    dead_reckoning: npt.NDArray[np.float64]
    """Dense dead reckoning at the navigation's rate, ``(m, 4)``."""
    navigation_rate: npt.NDArray[np.float64]
    """The optimised trajectory at the navigation's rate, ``(m, 4)``."""
    ground_truth: Optional[npt.NDArray[np.float64]]
    """Ground truth at the node stamps it covers, ``(k, 4)``, or None."""
    emitted: Optional[npt.NDArray[np.float64]]
    """Online runs: each node's estimate as emitted, ``(n, 4)``."""
    loops: Dict[str, Any]
    """Every loop-closure candidate as columns (see ``loops.csv``)."""
    report: Dict[str, Any]
    """The content of ``report.json``."""
    config: Dict[str, Any]
    """The effective configuration (``config.toml``)."""
    output: Optional[pathlib.Path]
    """The output folder, when one was written."""
    def __len__(self) -> int: ...

class Engine:
    """The online SLAM engine: push samples as they arrive (each stream in
    time order, the streams interleaved by time); each push returns the
    nodes it completed; ``finish()`` returns the ``RunResult``."""

    def __init__(
        self,
        config: Config = None,
        mounting: Optional[Mapping[str, Any]] = None,
        name: str = "online",
    ) -> None: ...
    def push_beam(
        self,
        stamp_s: float,
        angle_rad: float,
        bin_size_m: float,
        intensities: Union[npt.NDArray[np.uint8], bytes, Sequence[int]],
        first_bin_range_m: float = 0.0,
    ) -> List[Dict[str, Any]]:
        """Returns the completed nodes: dicts with ``node_id``,
        ``rotation_index``, ``stamp_s``, ``pose`` (``[x, y, yaw]``),
        ``poses`` (``(node_id + 1, 3)``) and ``latency_s``."""
    def push_dvl(
        self,
        stamp_s: float,
        velocity_mps: Sequence[float],
        valid: bool = True,
        covariance: Optional[Sequence[Sequence[float]]] = None,
    ) -> List[Dict[str, Any]]: ...
    def push_attitude(
        self,
        stamp_s: float,
        roll_rad: float,
        pitch_rad: float,
        yaw_rad: float,
        yaw_rate_radps: Optional[float] = None,
    ) -> List[Dict[str, Any]]: ...
    def end_of_data(self) -> List[Dict[str, Any]]:
        """The end of the data: returns the nodes that the last rotation
        and those still waiting complete (as ``push_beam``)."""
    @property
    def nodes(self) -> int: ...
    @property
    def poses(self) -> npt.NDArray[np.float64]: ...
    def finish(
        self, ground_truth: Optional[npt.NDArray[np.float64]] = None
    ) -> RunResult: ...

class OptimizeResult:
    ids: npt.NDArray[np.uint64]
    poses: npt.NDArray[np.float64]
    initial_chi2: float
    final_chi2: float
    iterations: int
    termination: str
    converged: bool
    time_s: float
    switched_off: List[int]
    summary: Dict[str, Any]

def load_mission(
    path: PathLike, topics: Optional[Mapping[str, str]] = None
) -> Mission:
    """An MCAP file, a rosbag2 folder or a St Pere log folder; ``topics``
    maps roles (sonar, dvl, heading, ground_truth) to ROS 2 topics."""

def simulate(
    scenario: str = "tank", seed: int = 1, config: Config = None
) -> Mission:
    """A built-in scenario (tank, marina, canyon) with ground truth."""

def run(
    mission: Union[Mission, PathLike],
    config: Config = None,
    output: Optional[PathLike] = None,
    online: bool = False,
) -> RunResult:
    """The SLAM pipeline of ``echofield run`` (``online=True``: ``run
    --online``)."""

def default_config(documented: bool = False) -> Any:
    """The default configuration: a dict, or with ``documented=True`` the
    TOML text of ``echofield config``."""

def optimize(
    graph: Optional[PathLike] = None,
    *,
    poses: Optional[npt.NDArray[np.float64]] = None,
    edges: Optional[npt.NDArray[np.float64]] = None,
    fixed: Sequence[int] = ...,
    solver: str = "lm",
    robust: str = "none",
    init: str = "chordal",
    max_iterations: Optional[int] = None,
    threads: int = 1,
    output: Optional[PathLike] = None,
) -> OptimizeResult:
    """A 2D pose graph solved as ``echofield optimize`` does."""

def evaluate(
    estimate: Trajectory,
    reference: Trajectory,
    align: str = "se2",
    max_time_diff: float = 0.01,
    rpe_distances: Sequence[float] = (10.0, 50.0),
) -> Dict[str, Any]:
    """ATE and RPE as ``echofield eval`` computes them."""
