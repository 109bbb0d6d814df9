"""probslam: probabilistic robot mapping and SLAM (Thrun, Burgard & Fox, ch. 9-11).

Units: metres and radians; poses are ``(x, y, theta)`` with theta wrapped to (-pi, pi].
"""

from ._core import (
    BeamSensorModel,
    BinaryMap2D,
    FastSlam,
    OccupancyGrid2D,
    OccupancyGrid3D,
    Pose2,
    fuse_max,
    inverse_range_sensor_model,
    landmark_from_range_bearing,
    landmark_from_range_bearing_jacobians,
    logit,
    map_log_posterior,
    probability_from_log_odds,
    range_bearing,
    range_bearing_jacobians,
    velocity_motion,
    velocity_motion_control_jacobian,
    velocity_motion_jacobian,
    wrap_angle,
)
from . import data, eval, inverse_learning, io, sim, slam
from .graph import OptimizationReport, PoseGraph2D, marginal_covariances, optimize, read_pose_graph, write_g2o
from .graphslam import (
    CorrespondenceTest,
    FeatureMerges,
    GraphSlamResult,
    Measurements,
    eif_construct,
    eif_correspondence_test,
    eif_initialize,
    eif_objective,
    eif_reduce,
    eif_solve,
    graph_slam,
)
from .ekf import EkfSlam, MapManagement, MultiHypothesisEkfSlam
from .mapping import MappingSummary, map_laser_log
from .map_occupancy import MapOccupancyResult, map_occupancy_grid_mapping
from .inverse_learning import LearnedInverseModel
from .slam import SlamResult, run_slam

__version__ = "0.1.0"


def _read_bt_with_file_check():
    """OccupancyGrid3D.read_bt, raising FileNotFoundError for a missing file as every reader of
    the package does (the compiled reader raises ValueError for it)."""
    import os

    from .io._files import require_existing

    compiled = OccupancyGrid3D.read_bt

    def read_bt(path: str, p_hit: float = 0.7, p_miss: float = 0.4, clamp_min: float = 0.1192,
                clamp_max: float = 0.971, occupancy_threshold: float = 0.5) -> "OccupancyGrid3D":
        path = os.fspath(path)
        require_existing(path)
        return compiled(path, p_hit, p_miss, clamp_min, clamp_max, occupancy_threshold)

    read_bt.__doc__ = (compiled.__doc__ or "") + "\nA missing file raises FileNotFoundError."
    read_bt.__name__, read_bt.__qualname__ = "read_bt", "OccupancyGrid3D.read_bt"
    return staticmethod(read_bt)


OccupancyGrid3D.read_bt = _read_bt_with_file_check()
del _read_bt_with_file_check

__all__ = [
    "BeamSensorModel",
    "BinaryMap2D",
    "MapOccupancyResult",
    "LearnedInverseModel",
    "inverse_learning",
    "map_log_posterior",
    "map_occupancy_grid_mapping",
    "EkfSlam",
    "FastSlam",
    "CorrespondenceTest",
    "data",
    "FeatureMerges",
    "GraphSlamResult",
    "Measurements",
    "OptimizationReport",
    "PoseGraph2D",
    "eif_construct",
    "eif_correspondence_test",
    "eif_initialize",
    "eif_objective",
    "eif_reduce",
    "eif_solve",
    "eval",
    "SlamResult",
    "run_slam",
    "slam",
    "graph_slam",
    "marginal_covariances",
    "optimize",
    "read_pose_graph",
    "write_g2o",
    "MapManagement",
    "MultiHypothesisEkfSlam",
    "MappingSummary",
    "OccupancyGrid2D",
    "OccupancyGrid3D",
    "Pose2",
    "fuse_max",
    "inverse_range_sensor_model",
    "io",
    "landmark_from_range_bearing",
    "landmark_from_range_bearing_jacobians",
    "logit",
    "map_laser_log",
    "probability_from_log_odds",
    "range_bearing",
    "sim",
    "range_bearing_jacobians",
    "velocity_motion",
    "velocity_motion_control_jacobian",
    "velocity_motion_jacobian",
    "wrap_angle",
]
