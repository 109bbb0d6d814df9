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
    chi_square_cdf,
    chi_square_quantile,
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
from .graph import (OptimizationReport, PoseGraph2D, marginal_covariances, optimize, read_pose_graph,
                    read_pose_graph_with_report, write_g2o)
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
    "read_pose_graph_with_report",
    "write_g2o",
    "MapManagement",
    "MultiHypothesisEkfSlam",
    "MappingSummary",
    "OccupancyGrid2D",
    "OccupancyGrid3D",
    "Pose2",
    "chi_square_cdf",
    "chi_square_quantile",
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
