"""Type stubs for probslam's C++ core. Units: metres, radians; poses are (x, y, theta)."""

import math
import os
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

ArrayLike = npt.ArrayLike
Array = npt.NDArray[np.float64]
Bounds = Tuple[float, float, float, float]  # (xmin, ymin, xmax, ymax), metres

MAX_COORDINATE: float  # m: the filters refuse coordinates beyond it (C++ kMaxCoordinate)

def chi_square_quantile(p: float, dof: int) -> float:
    """The x with P(X <= x) = p, X chi-square with dof degrees of freedom (a Mahalanobis gate)."""
def chi_square_cdf(x: float, dof: int) -> float:
    """P(X <= x) for X chi-square with dof degrees of freedom."""
@overload
def wrap_angle(angle: float) -> float: ...
@overload
def wrap_angle(angle: ArrayLike) -> Array: ...
@overload
def logit(p: float) -> float: ...
@overload
def logit(p: ArrayLike) -> Array: ...
@overload
def probability_from_log_odds(l: float) -> float: ...
@overload
def probability_from_log_odds(l: ArrayLike) -> Array: ...

class Pose2:
    """Planar pose; theta wrapped to (-pi, pi]."""
    x: float
    y: float
    theta: float
    def __init__(self, x: float = 0.0, y: float = 0.0, theta: float = 0.0) -> None: ...
    @staticmethod
    def from_array(array: ArrayLike) -> "Pose2": ...
    def as_array(self) -> Array: ...  # (3,)
    def compose(self, other: "Pose2") -> "Pose2": ...
    def __mul__(self, other: "Pose2") -> "Pose2": ...
    def inverse(self) -> "Pose2": ...
    def between(self, other: "Pose2") -> "Pose2": ...
    def transform_from(self, points: ArrayLike) -> Array: ...  # (2,) or (n, 2) body -> world
    def transform_to(self, points: ArrayLike) -> Array: ...  # (2,) or (n, 2) world -> body

class AckermannGeometry:
    """A car's geometry (m); defaults: the Victoria Park utility car."""
    def __init__(self, wheelbase: float = 2.83, encoder_offset: float = 0.76, sensor_ahead: float = 3.78,
                 sensor_left: float = 0.50) -> None: ...
    @property
    def wheelbase(self) -> float: ...
    @property
    def encoder_offset(self) -> float: ...
    @property
    def sensor_ahead(self) -> float: ...
    @property
    def sensor_left(self) -> float: ...

def ackermann_motion(pose: ArrayLike, speed: float, steering: float, dt: float,
                     geometry: Optional[AckermannGeometry] = None) -> Array:
    """(3,) the sensor's pose after dt s at encoder speed (m/s) and steering (rad)."""
def ackermann_motion_jacobian(pose: ArrayLike, speed: float, steering: float, dt: float,
                              geometry: Optional[AckermannGeometry] = None) -> Array:
    """(3, 3) G = dg/dpose."""
def ackermann_motion_control_jacobian(pose: ArrayLike, speed: float, steering: float, dt: float,
                                      geometry: Optional[AckermannGeometry] = None) -> Array:
    """(3, 2) V = dg/d(speed, steering)."""
def ackermann_increments(speed: ArrayLike, steering: ArrayLike, dt: ArrayLike, control_noise: ArrayLike,
                         geometry: Optional[AckermannGeometry] = None) -> Tuple[Array, Array]:
    """((N, 3) steps in the sensor's frame, (N, 3, 3) their covariances J M J^T)."""
def velocity_motion(pose: ArrayLike, v: float, w: float, dt: float) -> Array:
    """(3,) pose after v m/s, w rad/s for dt s (eq. 10.11); exact through w = 0."""
def velocity_motion_jacobian(pose: ArrayLike, v: float, w: float, dt: float) -> Array:
    """(3, 3) G = dg/dpose (Table 10.1 line 4, signs corrected)."""
def velocity_motion_control_jacobian(pose: ArrayLike, v: float, w: float, dt: float) -> Array:
    """(3, 2) V = dg/d(v, w)."""
def velocity_increments(v: ArrayLike, w: ArrayLike, dt: ArrayLike, control_noise: ArrayLike) -> Tuple[Array, Array]:
    """Motions (n, 3) of pieces (v, w, dt) from the origin and their covariances (n, 3, 3)."""
def range_bearing(pose: ArrayLike, landmark: ArrayLike) -> Array:
    """(2,) (range, bearing) of landmark (2,), or (3,) with its signature for a (3,) landmark."""
def range_bearing_jacobians(pose: ArrayLike, landmark: ArrayLike) -> Tuple[Array, Array]:
    """(d h/d pose (2, 3), d h/d landmark (2, 2)), or (3, 3) and (3, 3) with a signature."""
def landmark_from_range_bearing(pose: ArrayLike, z: ArrayLike) -> Array:
    """Table 10.1 line 10: landmark (2,) from z = (range, bearing), (3,) with a signature."""
def landmark_from_range_bearing_jacobians(pose: ArrayLike, z: ArrayLike) -> Tuple[Array, Array]:
    """(d m/d pose (2, 3), d m/d z (2, 2))."""

def inverse_range_sensor_model(cells_xy: ArrayLike, pose: ArrayLike, ranges: ArrayLike, beam_angles: ArrayLike,
                               z_max: float, alpha: float, beta: float, l0: float, l_occ: float,
                               l_free: float) -> Union[float, Array]:
    """Table 9.2 for cell centres (n, 2) -> (n,) log-odds, or one (2,) cell -> float."""

class OccupancyGrid2D:
    """2-D occupancy grid (ch. 9.2). Cell (row i, col j) covers x in [x0 + j res, x0 + (j+1) res),
    y in [y0 + i res, y0 + (i+1) res)."""
    resolution: float
    width: int
    height: int
    shape: Tuple[int, int]  # (height, width)
    origin: Tuple[float, float]  # (x0, y0) of cell (0, 0)'s lower-left corner
    p_prior: float
    l0: float  # logit(p_prior)
    clamp: Optional[Tuple[float, float]]  # probabilities; None: the textbook update
    p_hit: float
    p_miss: float
    log_odds: Array  # zero-copy, writable (height, width) view
    max_cells: int  # class attribute: the largest number of cells a grid may have
    def __init__(self, resolution: float, width: int, height: int, origin: ArrayLike = (0.0, 0.0),
                 p_prior: float = 0.5, clamp: Optional[Tuple[float, float]] = (0.1192, 0.971),
                 p_hit: float = 0.7, p_miss: float = 0.4) -> None: ...
    @staticmethod
    def covering(bounds: Bounds, resolution: float, p_prior: float = 0.5,
                 clamp: Optional[Tuple[float, float]] = (0.1192, 0.971), p_hit: float = 0.7,
                 p_miss: float = 0.4) -> "OccupancyGrid2D": ...
    def probability(self) -> Array: ...  # (height, width), eq. 9.6
    def cell_of(self, points: ArrayLike) -> npt.NDArray[np.int64]: ...  # (n, 2) xy -> (n, 2) (row, col)
    def cell_centers(self) -> Array: ...  # (height * width, 2), row-major
    def insert_cone_scan(self, pose: ArrayLike, ranges: ArrayLike, beam_angles: ArrayLike, z_max: float,
                         alpha: float, beta: float, l_occ: float, l_free: float) -> int: ...
    def insert_rays(self, pose: ArrayLike, ranges: ArrayLike, angles: ArrayLike, max_range: float) -> int: ...
    def insert_scans(self, poses: ArrayLike, ranges: ArrayLike, angles: ArrayLike, max_range: float) -> int: ...
    def clear_footprint(self, pose: ArrayLike, radius: float, l_free: Optional[float] = None) -> int: ...
    def add_log_odds(self, cells: ArrayLike, deltas: ArrayLike) -> int:
        """Table 9.1 line 4 with an inverse model evaluated elsewhere (ch. 9.3): l += deltas (n,)
        at the flat cell indices cells (n,) (row * width + col), clamped; all checked first."""
    def grown(self, bounds: Bounds) -> "OccupancyGrid2D": ...
    def copy(self) -> "OccupancyGrid2D": ...
    def same_geometry(self, other: "OccupancyGrid2D") -> bool: ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "OccupancyGrid2D":
        """The object saved at path; ValueError naming the path for any other or damaged file."""


class OccupancyGrid3D:
    """Sparse 3-D occupancy grid (ch. 9.2 in 3-D), hashed 8x8x8-voxel blocks, unbounded within
    OctoMap's key range (+-32768 voxels per axis). Updated with OctoMap 1.9.7's
    OcTree::insertPointCloud rules: same voxel keys, same float32 log-odds."""
    resolution: float  # voxel edge, m
    p_hit: float
    p_miss: float
    clamp: Tuple[float, float]  # (p_min, p_max) probabilities
    occupancy_threshold: float
    log_odds_hit: float  # float32 logit(p_hit)
    log_odds_miss: float
    log_odds_clamp: Tuple[float, float]
    num_known_voxels: int
    num_occupied_voxels: int
    num_blocks: int
    memory_bytes: int
    def __init__(self, resolution: float, p_hit: float = 0.7, p_miss: float = 0.4,
                 clamp: Tuple[float, float] = (0.1192, 0.971), occupancy_threshold: float = 0.5) -> None: ...
    def insert_point_cloud(self, points: ArrayLike, origin: ArrayLike, max_range: float = -1.0,
                           threads: int = 1) -> "InsertStats3D":
        """points (n, 3) m, origin (3,) m (rounded to float32); max_range m, < 0 unlimited. Returns
        the counts (InsertStats3D)."""
    @overload
    def log_odds_at(self, points: ArrayLike) -> npt.NDArray[np.float32]: ...  # (n, 3) -> (n,), NaN unknown
    @overload
    def log_odds_at(self, points: Tuple[float, float, float]) -> float: ...
    def is_occupied(self, points: ArrayLike) -> Union[bool, npt.NDArray[np.bool_]]: ...
    def cast_ray(self, origin: ArrayLike, direction: ArrayLike, max_range: float) -> Optional[Array]:
        """Centre (3,) of the first occupied voxel within max_range m, or None."""
    def known_voxels(self) -> Tuple[Array, npt.NDArray[np.float32]]: ...  # centres (n, 3), log-odds (n,)
    def occupied_voxels(self) -> Tuple[Array, npt.NDArray[np.float32]]: ...
    def project_2d(self, z_min: float = -1.7976931348623157e+308,
                   z_max: float = 1.7976931348623157e+308) -> OccupancyGrid2D:
        """Column-wise maximum log-odds of known voxels with centre z in [z_min, z_max]."""
    def write_bt(self, path: Union[str, os.PathLike[str]]) -> int:
        """OctoMap .bt file (occupancy bits only); returns the number of tree nodes."""
    @staticmethod
    def read_bt(path: Union[str, os.PathLike[str]], p_hit: float = 0.7, p_miss: float = 0.4,
                clamp: Tuple[float, float] = (0.1192, 0.971), occupancy_threshold: float = 0.5) -> "OccupancyGrid3D":
        """OctoMap .bt file; voxels get the clamped log-odds. FileNotFoundError for a missing file,
        ValueError for a bad one."""
    def clear(self) -> None: ...
    def copy(self) -> "OccupancyGrid3D":
        """An independent deep copy."""
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit (every block's float
        log-odds, unlike write_bt's occupancy bits)."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "OccupancyGrid3D":
        """The object saved at path; ValueError naming the path for any other or damaged file."""

class InsertStats3D:
    """What one OccupancyGrid3D.insert_point_cloud did with its points."""
    points: int  # given
    skipped_nonfinite: int  # NaN or infinite coordinates: left out
    out_of_bounds: int  # end voxel outside OctoMap's key range
    max_range_cut: int  # beyond max_range: they only clear, up to it
    voxels_updated: int  # changed by this scan, each at most once

def fuse_max(grids: Sequence[OccupancyGrid2D]) -> OccupancyGrid2D:
    """Eq. 9.9: cell-wise most pessimistic map of grids of equal geometry."""

class BinaryMap2D:
    """A binary occupancy map on an OccupancyGrid2D's lattice (what forward models see)."""
    shape: Tuple[int, int]  # (height, width)
    resolution: float  # m per cell
    origin: Tuple[float, float]  # (x0, y0) m of cell (0, 0)'s lower-left corner
    occupied: Array  # (height, width) bool, a copy
    def __init__(self, grid: OccupancyGrid2D, occupied: ArrayLike) -> None:
        """grid's geometry with occupied (height, width) bool (or 0/1 integers; floats: TypeError)."""
    @staticmethod
    def from_grid(grid: OccupancyGrid2D) -> "BinaryMap2D":
        """grid thresholded: occupied iff p > 0.5 (log-odds > 0)."""

class BeamSensorModel:
    """Beam-based forward model p(z | x, m) of a range finder (Probabilistic Robotics ch. 6.3,
    Table 6.1): z_hit * truncated N(z*, sigma_hit^2) on [0, max_range] + z_short * truncated
    exponential(lambda_short) on [0, z*] + z_max * [z >= max_range] + z_rand / max_range, where
    z* is the expected range on a binary map: for shape "laser" the distance at which the ray
    enters the first occupied cell of the grid's exact ray walk; for "sonar" the distance to the
    nearest occupied cell centre within beta/2 of the beam. z_max here is the *weight* of max
    readings (the book's name); the range limit is max_range. Weights >= 0 summing to 1 (within
    1e-9); sigma_hit (m), lambda_short (1/m), max_range (m) > 0; beta (rad) in (0, 2 pi] for a
    sonar. ValueError naming the parameter otherwise. Maps: BinaryMap2D or OccupancyGrid2D
    (thresholded at p > 0.5)."""
    shape: str  # "laser" or "sonar"
    max_range: float
    beta: float
    z_hit: float
    z_short: float
    z_max: float
    z_rand: float
    sigma_hit: float
    lambda_short: float
    def __init__(self, shape: str, max_range: float, beta: float = 0.0, z_hit: float = 0.85,
                 z_short: float = 0.05, z_max: float = 0.05, z_rand: float = 0.05, sigma_hit: float = 0.05,
                 lambda_short: float = 1.0) -> None: ...
    def probability(self, z: ArrayLike, z_expected: ArrayLike) -> Array:
        """Eq. 6.12 for readings z (n,) m given expected ranges (n,) m: densities per metre, plus the
        max-reading indicator's weight (eq. 6.10) where z >= max_range."""
    def expected_ranges(self, pose: ArrayLike, beam_angles: ArrayLike, map: Union["BinaryMap2D", OccupancyGrid2D]) -> Array:
        """z* (B,) m of each beam from pose (3,) at beam_angles (B,) rad relative to the heading."""
    def log_likelihood(self, ranges: ArrayLike, pose: ArrayLike, beam_angles: ArrayLike,
                       map: Union["BinaryMap2D", OccupancyGrid2D]) -> Array:
        """log p(z_k | x, m) (B,) per beam (nats). ranges (B,) m: >= 0, no NaN (ValueError); inf is a
        max reading."""
    def sample(self, pose: ArrayLike, beam_angles: ArrayLike, map: Union["BinaryMap2D", OccupancyGrid2D],
               rng: Union[int, np.random.Generator]) -> Array:
        """One reading (B,) m per beam drawn from p(z | x, m); rng: a seed >= 0 or a Generator."""

def map_occupancy_grid_mapping(poses: ArrayLike, scans: ArrayLike, beam_angles: ArrayLike, model: BeamSensorModel,
                               grid: OccupancyGrid2D, prior: Union[None, float, ArrayLike] = None, *,
                               max_sweeps: int = 1000, scoring: str = "incremental", max_evaluations: int = 0,
                               record_trace: bool = False, sensitivity: bool = True) -> Dict[str, Any]:
    """Table 9.3 (see probslam.map_occupancy_grid_mapping, which wraps the dict in a dataclass)."""

def map_log_posterior(map: Union[BinaryMap2D, OccupancyGrid2D], poses: ArrayLike, scans: ArrayLike,
                      beam_angles: ArrayLike, model: BeamSensorModel, prior: Union[float, ArrayLike]) -> float:
    """Eq. 9.24 of a binary map (nats): sum of log p(z | x, m) over readings, every expected range
    cast from scratch, plus sum of l0_i = logit(prior_i) over occupied cells. poses (T, 3), scans
    (T, B) m, beam_angles (B,) or (T, B) rad, prior a number or (H, W) probabilities."""

CARMEN_MAX_REPORTED_LINES: int  # skipped lines a log reader reports by number and reason
def read_carmen_log(path: str) -> dict: ...
def parse_carmen_log(text: str, source: str = "<text>") -> dict: ...
QUATERNION_NORM_TOLERANCE: float  # 3-D graph files: a quaternion further than this from unit norm is refused
def save_ros_map(grid: OccupancyGrid2D, yaml_path: str, occupied_thresh: float = 0.65,
                 free_thresh: float = 0.196) -> None: ...
def load_ros_map(yaml_path: str) -> OccupancyGrid2D: ...

# --- EKF SLAM (ch. 10); the public face is probslam.ekf.EkfSlam -------------------------------
class Association:
    """How update_unknown pairs a scan's measurements with landmarks."""
    MAXIMUM_LIKELIHOOD: "Association"  # Table 10.2, the best pairs first
    JOINT_COMPATIBILITY: "Association"  # JCBB over the scan (Neira & Tardos 2001)
    name: str
    value: int
    def __init__(self, value: int) -> None: ...
    def __int__(self) -> int: ...

class Landmarks:
    """One map's landmarks (EkfSlam.landmarks(), FastSlam.landmarks(particle)); len() is N."""
    ids: npt.NDArray[np.int64]  # (N,)
    means: Array  # (N, 2) positions, m
    covariances: Array  # (N, 2, 2) position covariances, m^2
    def __len__(self) -> int: ...

class _EkfSlam:
    state_dim: int
    landmark_dim: int
    num_landmarks: int
    num_provisional: int
    capacity: int
    mean: Array  # (state_dim,) zero-copy view: pose, then each landmark's x, y
    signatures: Array  # (num_landmarks, 2) signature mean, variance (a copy)
    covariance: Array  # (state_dim, state_dim) zero-copy view
    pose: Array  # (3,)
    map_management: MapManagement
    gate_distance: float  # m
    def __init__(self, motion_noise: ArrayLike, measurement_noise: ArrayLike, use_signatures: bool,
                 initial_pose: ArrayLike, initial_pose_cov: ArrayLike) -> None: ...
    def landmarks(self) -> Landmarks:
        """The map, in state order."""
    def landmark(self, id: int) -> Array: ...
    def landmark_covariance(self, id: int) -> Array: ...
    def existence(self, id: int) -> float: ...
    def has_landmark(self, id: int) -> bool: ...
    def predict(self, v: float, w: float, dt: float, noise: Optional[ArrayLike] = None) -> None: ...
    def predict_odometry(self, delta: ArrayLike, noise: ArrayLike) -> None: ...
    def predict_odometry_batch(self, deltas: ArrayLike, noises: ArrayLike) -> Array:
        """predict_odometry for each row of deltas (K, 3) with noises (K, 3, 3); the poses after each step (K, 3)."""
    def update(self, z: ArrayLike, ids: ArrayLike, gate: float = math.inf) -> Tuple[Array, npt.NDArray[np.bool_]]: ...
    def update_unknown(self, z: ArrayLike, alpha: float, alpha_new: float,
                       association: Association = Association.MAXIMUM_LIKELIHOOD) -> Tuple[npt.NDArray[np.int64], Array,
                                                                npt.NDArray[np.int64], npt.NDArray[np.int64]]:
        """(ids, smallest pi, outcome, removed ids) for a scan z (k, 2) or (k, 3)."""
    def remove_landmark(self, id: int) -> None: ...
    def copy(self) -> "_EkfSlam":
        """An independent copy with its own storage."""
    def pairing_likelihood(self, z: ArrayLike, id: int) -> Tuple[float, float]:
        """(NIS, log det(2 pi S)) of one measurement against landmark id, without updating."""
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "_EkfSlam":
        """The object saved at path; ValueError naming the path for any other or damaged file."""


class FastSlamUpdateResult:
    """What FastSlam.update did."""
    resampled: bool

class FastSlamAssociationResult:
    """What FastSlam.update_unknown did with a scan's k measurements; row j is particle j after
    any resampling of the call."""
    ids: npt.NDArray[np.int64]  # (M, k) landmark used or created
    is_new: npt.NDArray[np.bool_]  # (M, k)
    removed: npt.NDArray[np.int64]  # (R, 2) rows (particle, landmark id) removed (negative information, unconfirmed provisional)
    resampled: bool

class LandmarkDetails:
    """A particle's landmarks beyond their position, in the order of FastSlam.landmarks."""
    ids: npt.NDArray[np.int64]  # (N,)
    existence: Array  # (N,) existence counters
    signature: Array  # (N,)
    signature_var: Array  # (N,)
    def __len__(self) -> int: ...

class MapSharing:
    """How much of FastSlam's particle maps and paths is shared."""
    distinct_nodes: int  # tree nodes allocated for all maps
    total_nodes: int  # sum of per-particle tree nodes: what deep copies would hold
    landmarks: int  # sum of per-particle landmark counts
    path_nodes: int  # distinct path chunks

class FastSlam:
    """FastSLAM 1.0 / 2.0 (Montemerlo 2002, 2003; Probabilistic Robotics ch. 13) for point
    landmarks seen by a range-bearing(-signature) sensor. Units: metres, radians, seconds.

    Args:
        motion_noise: (3, 3) pose-space covariance R of (x, y, theta) added to g(x, u), or (2, 2)
            control-space covariance M of (v [m/s], w [rad/s]); positive semi-definite (zero
            allowed: noise-free motion).
        measurement_noise: Q, (2, 2) covariance of (range [m], bearing [rad]), or (3, 3) with the
            signature's variance (uncorrelated with range and bearing) when ``use_signatures``.
        initial_pose: (3,) every particle's start pose.
        options: a FastSlamOptions (None: the defaults): num_particles, version (1 or 2), seed,
            threads, p_new, the association, negative information, provisional landmarks, the
            bearing offset; each field by keyword replaces options' field (``num_particles=50``).

    Every call validates its input first and raises ValueError / TypeError naming the argument or
    the option's field, the filter unchanged. Calls release the GIL and are serialised by a
    per-filter lock.
    """
    options: FastSlamOptions  # a copy of the options it runs with
    motion_noise: Array  # as given (symmetrised): (3, 3) pose space or (2, 2) control space
    measurement_noise: Array  # Q (symmetrised)
    initial_pose: Array  # (3,) every particle's start pose (heading wrapped)
    num_particles: int
    version: int
    landmark_dim: int
    use_signatures: bool
    pose: Array  # (3,) the best particle's pose
    poses: Array  # (M, 3) particle poses
    log_weights: Array  # (M,) normalised (log-sum-exp 0)
    weights: Array  # (M,) summing to 1
    bearing_offsets: Array  # (M,) each particle's bearing offset (rad) of its last update
    last_log_likelihoods: Array  # (M,) log of each particle's weight factor in the last update
    effective_sample_size: float  # N_eff = 1 / sum w^2
    best_index: int  # particle of highest weight
    mean_pose: Array  # (3,) weighted mean, heading by circular mean
    pose_covariance: Array  # (3, 3) weighted covariance about mean_pose
    num_resamples: int
    resampled: bool  # whether the last update resampled
    ancestors: npt.NDArray[np.int32]  # (M,) after a resampling: particle j's ancestor; else (0,)
    map_sharing: MapSharing
    num_landmarks: int  # in the best particle's map
    def __init__(self, motion_noise: ArrayLike, measurement_noise: ArrayLike, *,
                 initial_pose: ArrayLike = (0.0, 0.0, 0.0), options: Optional[FastSlamOptions] = None,
                 num_particles: int = 100, version: int = 1, use_signatures: bool = False, seed: int = 0,
                 threads: int = 1, resample_threshold: float = 0.5, p_new: float = 0.01,
                 outlier_density: float = 0.0, association_radius: float = 2.0, joint_association: bool = True,
                 cell_size: float = 2.0, negative_information: bool = False, existence_hit: float = 1.0,
                 existence_miss: float = 1.0, sensor_range: float = math.inf,
                 sensor_fov: float = 6.283185307179586, min_sightings: int = 1, provisional_max_age: int = 20,
                 record_path: bool = True, bearing_offset_sigma: float = 0.0,
                 bearing_offset_correlation: float = 0.0) -> None: ...
    def predict(self, v: float, w: float, dt: float) -> None:
        """Samples each particle's pose from the velocity motion model (v m/s, w rad/s, dt s)."""
    def predict_odometry(self, delta: ArrayLike, noise: ArrayLike) -> None:
        """x <- x (+) (delta + e), e ~ N(0, noise (3, 3)) in the robot frame."""
    def predict_odometry_batch(self, deltas: ArrayLike, noises: ArrayLike) -> None:
        """predict_odometry(deltas[k], noises[k]) for k = 0 .. K - 1, in one call: deltas (K, 3), noises (K, 3, 3)."""
    def update(self, z: ArrayLike, ids: ArrayLike) -> FastSlamUpdateResult:
        """Known correspondences: z (k, 2) or (k, 3), ids (k,) >= 0."""
    def update_unknown(self, z: ArrayLike, p_new: Optional[float] = None) -> FastSlamAssociationResult:
        """Per-particle maximum-likelihood correspondences for a scan z (k, 2) or (k, 3)."""
    def resample(self) -> None:
        """Low-variance resampling now, whatever N_eff."""
    def copy(self) -> "FastSlam": ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "FastSlam":
        """The object saved at path; ValueError naming the path for any other or damaged file."""
    def path(self, particle: Optional[int] = None) -> Array:
        """(T + 1, 3) a particle's path, oldest first (default: the best particle's)."""
    def landmarks(self, particle: Optional[int] = None) -> Landmarks:
        """A particle's map, sorted by id (default: the best particle's)."""
    def landmark_details(self, particle: Optional[int] = None) -> LandmarkDetails:
        """existence, signature, signature_var of a particle's landmarks, in landmarks()'s order."""

def low_variance_resample(weights: ArrayLike, offset: float) -> npt.NDArray[np.int32]:
    """Systematic resampling: indices drawn at (offset + m) / M, m = 0..M-1, offset in [0, 1)."""
def fastslam2_proposal(pose_mean: ArrayLike, pose_cov: ArrayLike, landmark_mean: ArrayLike,
                       landmark_cov: ArrayLike, z: ArrayLike, measurement_noise: ArrayLike
                       ) -> Tuple[Array, Array, float]:
    """FastSLAM 2.0's proposal for one measurement: (mean (3,), cov (3, 3), log N(z - z_hat; 0,
    G_x pose_cov G_x^T + Q_j))."""
def _persistent_tree_nodes() -> int: ...

class _MultiHypothesisEkfSlam:
    best: _EkfSlam  # a copy of the cheapest filter
    pose: Array  # (3,) the cheapest filter's
    num_hypotheses: int
    total_cost: float
    costs: Array  # (H,) above the best, ascending
    options: MultiHypothesisOptions
    def __init__(self, initial: _EkfSlam, options: MultiHypothesisOptions) -> None: ...
    def predict(self, v: float, w: float, dt: float, noise: Optional[ArrayLike] = None) -> None: ...
    def update(self, z: ArrayLike) -> npt.NDArray[np.int64]: ...
    def history(self) -> List[npt.NDArray[np.int64]]: ...
    def copy(self) -> "_MultiHypothesisEkfSlam": ...

# --- graph/: pose graphs (ch. 11); the public face is probslam.graph ---------------------------
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "_MultiHypothesisEkfSlam":
        """The object saved at path; ValueError naming the path for any other or damaged file."""

class PoseGraph2D:
    """A planar pose/landmark graph: pose vertices (x m, y m, theta rad), point vertices (x, y) m,
    pose edges (relative pose of `to` in `from`'s frame) and point edges (the point in the pose's
    frame), each with an information matrix (g2o's EDGE_SE2 / EDGE_SE2_XY). Ids are shared by
    poses and points."""
    num_vertices: int
    num_pose_edges: int
    num_point_edges: int
    pose_ids: npt.NDArray[np.int64]  # (P,) in the order added
    point_ids: npt.NDArray[np.int64]  # (L,)
    landmark_ids: npt.NDArray[np.int64]  # (L,) iSAM's LANDMARK numbers
    poses: Array  # (P, 3) m, m, rad
    points: Array  # (L, 2) m
    def __init__(self) -> None: ...
    def add_pose(self, id: int, pose: ArrayLike) -> None: ...
    def add_point(self, id: int, point: ArrayLike) -> None: ...
    def add_pose_edge(self, from_id: int, to_id: int, measurement: ArrayLike, information: ArrayLike) -> None:
        """measurement (3,) to_id's pose in from_id's frame; information (3, 3)."""
    def add_point_edge(self, pose_id: int, point_id: int, measurement: ArrayLike, information: ArrayLike) -> None:
        """measurement (2,) m the point in pose_id's frame; information (2, 2)."""
    def set_fixed(self, id: int, fixed: bool = True) -> None: ...
    def is_fixed(self, id: int) -> bool: ...
    def set_poses(self, ids: ArrayLike, poses: ArrayLike) -> None: ...  # (N,), (N, 3)
    def set_points(self, ids: ArrayLike, points: ArrayLike) -> None: ...  # (N,), (N, 2)
    def has_vertex(self, id: int) -> bool: ...
    def edge_ids(self) -> npt.NDArray[np.int64]: ...  # (E, 2): pose edges, then point edges
    def pose_edges(self) -> Tuple[npt.NDArray[np.int64], Array, Array]: ...  # (E, 2), (E, 3), (E, 3, 3)
    def point_edges(self) -> Tuple[npt.NDArray[np.int64], Array, Array]: ...  # (E, 2), (E, 2), (E, 2, 2)
    def chi2(self) -> float: ...
    def copy(self) -> "PoseGraph2D": ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "PoseGraph2D":
        """The object saved at path; ValueError naming the path for any other or damaged file."""


class PoseGraph3D:
    """A 3-D pose graph: poses (7,) [x, y, z, qx, qy, qz, qw] (m, unit quaternion; g2o's
    VERTEX_SE3:QUAT order), edges the pose of `to` in `from`'s frame with (6, 6) information in
    g2o's EDGE_SE3:QUAT order [translation, rotation]; error [t_e, Log(R_e)] of
    z^-1 x_from^-1 x_to. Points (3,) m share the poses' id space; a point edge (g2o
    EDGE_SE3_TRACKXYZ) has error (x_pose * offset)^-1 p - z and (3, 3) information."""
    QUATERNION_NORM_TOLERANCE: float
    num_vertices: int  # poses plus points
    num_points: int
    num_pose_edges: int
    num_point_edges: int
    pose_ids: npt.NDArray[np.int64]  # (P,) in the order added
    poses: Array  # (P, 7) x, y, z m, qx, qy, qz, qw
    point_ids: npt.NDArray[np.int64]  # (L,) in the order added
    points: Array  # (L, 3) m
    def __init__(self) -> None: ...
    def add_pose(self, id: int, pose: ArrayLike) -> None: ...
    def add_point(self, id: int, point: ArrayLike) -> None: ...  # (3,) m
    def add_point_edge(self, pose_id: int, point_id: int, measurement: ArrayLike, information: ArrayLike,
                       offset: Optional[ArrayLike] = None) -> None:
        """measurement (3,) the point in the frame of the sensor at offset (7,) on the pose (None: the
        pose itself); information (3, 3)."""
    def add_pose_edge(self, from_id: int, to_id: int, measurement: ArrayLike, information: ArrayLike) -> None:
        """measurement (7,) to_id's pose in from_id's frame; information (6, 6)."""
    def add_pose_prior(self, id: int, measurement: ArrayLike, information: ArrayLike) -> None:
        """g2o's EDGE_SE3_PRIOR: error [t_e, Log(R_e)] of z^-1 x; information (6, 6)."""
    def set_fixed(self, id: int, fixed: bool = True) -> None: ...
    def is_fixed(self, id: int) -> bool: ...
    def set_poses(self, ids: ArrayLike, poses: ArrayLike) -> None: ...  # (N,), (N, 7)
    def set_points(self, ids: ArrayLike, points: ArrayLike) -> None: ...  # (N,), (N, 3)
    def has_vertex(self, id: int) -> bool: ...
    def edge_ids(self) -> npt.NDArray[np.int64]: ...  # (E + M, 2): pose edges, then point edges (pose, point)
    def pose_edges(self) -> Tuple[npt.NDArray[np.int64], Array, Array]: ...  # (E, 2), (E, 7), (E, 6, 6)
    def point_edges(self) -> Tuple[npt.NDArray[np.int64], Array, Array, Array]: ...  # (M, 2), (M, 3), (M, 3, 3), (M, 7)
    num_pose_priors: int
    def pose_priors(self) -> Tuple[npt.NDArray[np.int64], Array, Array]: ...  # (P,), (P, 7), (P, 6, 6)
    def prior_chi2(self) -> Array: ...  # (P,)
    def edge_chi2(self) -> Array: ...  # (E + M,) pose edges, then point edges
    def chi2(self) -> float: ...  # edges and priors
    def copy(self) -> "PoseGraph3D": ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "PoseGraph3D":
        """The object saved at path; ValueError naming the path for any other or damaged file."""


def read_pose_graph_3d(path: str, format: str = "auto", noise: str = "default",
                       rows: str = "strict") -> Tuple[PoseGraph3D, "PoseGraphReadReport"]: ...
def write_g2o_3d(path: str, graph: PoseGraph3D) -> None: ...


class OptimizationReport:
    iterations: int
    initial_chi2: float
    chi2: float  # g2o's chi2 at the end
    objective: float  # the robust objective (chi2 without a kernel)
    converged: bool
    stop_reason: str
    chi2_history: List[float]
    iteration_seconds: List[float]
    factor_nonzeros: int

class IncrementalReport:
    steps: int
    iterations: int
    chi2: float
    step_chi2: List[float]

def optimize(graph: Union[PoseGraph2D, PoseGraph3D], *, options: Optional[OptimizerOptions] = None,
             callback: Optional[Callable[[int, float], Optional[bool]]] = None, algorithm: str = 'gauss-newton',
             damping: str = 'marquardt', max_iterations: int = 100, relative_tolerance: float = 1e-10,
             step_tolerance: float = 1e-10, kernel: str = 'none', kernel_width: float = 1.0,
             linear_solver: SparseCholeskyOptions = ...) -> OptimizationReport:
    """In place from the current values with ``options`` (an OptimizerOptions; None: its defaults)
    and its fields by keyword (``max_iterations=5``, ``linear_solver={"ordering": "amd"}``); the fill
    ordering "default" is "amd" for 2-D, "metis" for 3-D. callback(iteration, chi2) after each
    completed iteration: False stops; an exception it raises leaves the graph at the last completed
    iteration. A 3-D step is x (+) [v, w] = (R Exp(w), t + R v). TypeError naming graph for any
    other type; errors name an option's path ("linear_solver.ordering")."""
def optimize_incremental(graph: Union[PoseGraph2D, PoseGraph3D], *, options: Optional[IncrementalOptions] = None,
                         poses_per_step: int = 100, step: OptimizerOptions = ...) -> IncrementalReport:
    """Poses join in the order added; the graph so far is optimised every poses_per_step poses with
    options.step (IncrementalOptions; its defaults stop sooner than optimize's); fields by keyword
    (``poses_per_step=25``, ``step={"max_iterations": 3}``), errors naming the path ("step.kernel")."""
def initialize_odometry(graph: Union[PoseGraph2D, PoseGraph3D]) -> None:
    """Composes pose edges outward along a breadth-first spanning tree (dead reckoning)."""
def initialize_chordal(graph: PoseGraph3D, *, options: Optional[SparseCholeskyOptions] = None,
                       method: str = 'supernodal', ordering: str = 'default') -> None:
    """Rotations by the chordal relaxation (projected onto SO(3)), then translations: exact without noise.
    options: the linear solves' SparseCholeskyOptions (fields by keyword as for optimize)."""
def marginal_covariances(graph: Union[PoseGraph2D, PoseGraph3D], ids: Sequence[int], *,
                         options: Optional[SparseCholeskyOptions] = None, method: str = 'supernodal',
                         ordering: str = 'default') -> List[Array]:
    """2-D: (3, 3) per pose id, (2, 2) per point id; 3-D: (6, 6) per pose id in its tangent
    [translation, rotation vector], (3, 3) per point; zero for a fixed vertex. options: a
    SparseCholeskyOptions (fields by keyword: method, ordering)."""
def joint_marginal_covariances(graph: Union[PoseGraph2D, PoseGraph3D], groups: Sequence[Sequence[int]], *,
                               options: Optional[SparseCholeskyOptions] = None, method: str = 'supernodal',
                               ordering: str = 'default') -> List[Array]:
    """Per group, the joint covariance of its vertices stacked in order (2-D: 3 per pose, 2 per
    point; 3-D: 6 and 3), cross-covariances included; zero rows and columns for a fixed vertex.
    options as for marginal_covariances."""
class PoseGraphReadReport:
    """What read_pose_graph_with_report did with the file's records."""
    rows: int  # records read, skipped ones included
    skipped_rows: int  # 0 under rows="strict"
    skipped_lines: List[int]  # the first POSE_GRAPH_MAX_REPORTED_LINES skipped, 1-based
    skipped_reasons: List[str]  # why each of skipped_lines was skipped
    equivalences: int  # TORO EQUIV records read (applied under equivalences="merge" only)
    merged_vertices: int  # vertex ids merged into another by them
    collapsed_edges: int  # edges dropped because both their ends became one vertex
    repaired_rows: int  # records whose information was not positive definite, repaired
    repaired_lines: List[int]  # line numbers of the first POSE_GRAPH_MAX_REPORTED_LINES repaired records
    repaired_reasons: List[str]  # what was repaired in each of repaired_lines
MAX_BAD_ROW_FRACTION: float  # rows="skip": more than this fraction of records skipped is fatal
INFORMATION_EIGENVALUE_FLOOR: float  # a non-positive-definite information's eigenvalues raised to this x the largest
POSE_GRAPH_MAX_REPORTED_LINES: int  # skipped records a PoseGraphReadReport lists by line and reason
def read_pose_graph(path: str, format: str = "auto", noise: str = "default", rows: str = "strict",
                    equivalences: str = "merge") -> PoseGraph2D:
    """format "auto", "g2o", "toro" or "isam"; noise "default", "information", "sqrt_information" or
    "covariance"; rows "strict" or "skip"; equivalences (TORO EQUIV) "merge" or "ignore"."""
def read_pose_graph_with_report(path: str, format: str = "auto", noise: str = "default",
                                rows: str = "skip", equivalences: str = "merge") -> Tuple[PoseGraph2D, PoseGraphReadReport]:
    """As read_pose_graph, with what was skipped."""
def write_g2o(path: str, graph: PoseGraph2D) -> None: ...
def write_isam(path: str, graph: PoseGraph2D) -> None: ...
def linearize_pose_edges(from_poses: ArrayLike, to_poses: ArrayLike, measurements: ArrayLike) -> Tuple[Array, Array, Array]: ...
def linearize_point_edges(poses: ArrayLike, points: ArrayLike, measurements: ArrayLike) -> Tuple[Array, Array, Array]: ...

# --- slam2d/: scan matching and GraphSLAM over submaps (ch. 11.7) ---------------------------

def scan_hits(ranges: ArrayLike, beam_angles: ArrayLike, max_range: float = math.inf, min_range: float = 0.0,
              max_usable_range: float = 30.0, min_point_spacing: float = 0.0) -> Array:
    """(N, 2) hit points in the sensor frame, metres; no-return readings (>= max_range, inf, NaN) never hit."""
def ranges_for_insertion(ranges: ArrayLike, max_range: float = math.inf, min_range: float = 0.0,
                         max_usable_range: float = 30.0, clear_no_return: bool = True) -> Tuple[Array, float]:
    """((B,) ranges, usable_range m) for OccupancyGrid2D.insert_rays(max_range=usable_range): no-return
    beams clear only."""

class LikelihoodField:
    """The blurred likelihood field of a grid: log((1 - p_rand) exp(-d^2 / 2 sigma^2) + p_rand)."""
    resolution: float
    origin: Tuple[float, float]
    shape: Tuple[int, int]  # (rows, cols)
    num_occupied: int
    floor_value: float  # log p_rand
    sigma: float
    p_rand: float
    truncation: float
    distance: npt.NDArray[np.float32]  # (rows, cols) metres to the nearest occupied cell
    log_likelihood: npt.NDArray[np.float32]
    def __init__(self, grid: OccupancyGrid2D, sigma: float = 0.05, p_rand: float = 0.05,
                 occupied_threshold: float = 0.5, max_distance: float = 0.0,
                 region: Optional[ArrayLike] = None) -> None: ...
    def interpolate_distance(self, points: ArrayLike) -> Tuple[Array, Array]:
        """(N,) bilinear distances and (N, 2) their gradients at world points (N, 2)."""

class MatchResult:
    found: bool  # False: nothing reached min_score (pose = prior)
    pose: Array  # (3,) refined
    search_pose: Array  # (3,) on the search lattice
    covariance: Array  # (3, 3)
    score: float
    search_score: float
    match_quality: float  # mean hit likelihood, 0..1
    num_points: int
    candidates_scored: int
    angular_steps: int
    angular_step: float  # rad

class CorrelativeScanMatcher:
    """Correlative scan matching (Olson 2009), branch and bound over a max-pooled pyramid (Hess 2016)."""
    max_level: int
    field: LikelihoodField
    def __init__(self, field: LikelihoodField, max_level: int = 6) -> None: ...
    def match(self, points: ArrayLike, prior: ArrayLike, linear_window: float = 0.3, angular_window: float = 0.35,
              angular_step: float = 0.0, prior_covariance: Optional[ArrayLike] = None, refine: bool = True,
              brute_force: bool = False, min_translation_std: float = 0.0, min_rotation_std: float = 0.0,
              min_score: float = -math.inf) -> MatchResult: ...
    def smooth_score(self, points: ArrayLike, pose: ArrayLike, prior: Optional[ArrayLike] = None,
                     prior_covariance: Optional[ArrayLike] = None) -> float: ...
    def runner_up(self, points: ArrayLike, prior: ArrayLike, best: MatchResult, distinct_chi2: float,
                  linear_window: float = 0.3, angular_window: float = 0.35, angular_step: float = 0.0,
                  refine: bool = True, brute_force: bool = False, min_score: float = -math.inf,
                  admitted: Optional[ArrayLike] = None) -> MatchResult: ...
    def closeness(self, points: ArrayLike, a: ArrayLike, b: ArrayLike) -> float: ...

class IncrementalScanMatcher:
    """Each scan matched against the map so far (the lecture's scan matching), into local submaps.
    IncrementalScanMatcher(*, options=None, **fields): an IncrementalScanMatcherOptions, fields by
    keyword replacing its (errors name the field's path, "filter.max_range")."""
    options: IncrementalScanMatcherOptions  # a copy
    num_scans: int
    num_submaps: int
    pose: Array  # (3,) the last scan's pose
    scan_poses: Array  # (S, 3)
    timestamps: Array  # (S,)
    scan_info: Array  # (S, 5): matched, fallback, submap, match_quality, points
    def __init__(self, *, options: Optional[IncrementalScanMatcherOptions] = None, resolution: float = 0.05,
                 filter: ScanFilter = ..., field: LikelihoodFieldOptions = ..., match: MatchOptions = ...,
                 odometry: OdometryNoise = ..., use_odometry_prior: bool = True, constant_velocity: bool = False,
                 match_fraction: float = 1.0, update: UpdateTrigger = ..., submap_distance: float = 5.0,
                 submap_scans: int = 0, min_match_quality: float = 0.1, warmup_scans: int = 1,
                 field_refresh_distance: float = 0.3, field_refresh_angle: float = 0.3,
                 search: str = 'fallback') -> None: ...
    def add_scans(self, ranges: ArrayLike, beam_angles: ArrayLike, odometry: ArrayLike,
                  timestamps: ArrayLike) -> None:
        """ranges (S, B) m, beam_angles (B,) or (S, B) rad, odometry (S, 3) laser poses, timestamps (S,) s."""
    def copy(self) -> "IncrementalScanMatcher": ...
    def submap_grid(self, index: int) -> OccupancyGrid2D: ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "IncrementalScanMatcher":
        """The object saved at path; ValueError naming the path for any other or damaged file."""

class SubmapConstraints:
    """SubmapSlam2D.constraints: one row per constraint between submaps (C rows)."""
    from_submap: npt.NDArray[np.int32]  # (C,)
    to_submap: npt.NDArray[np.int32]  # (C,)
    measurement: Array  # (C, 3) to_submap's origin in from_submap's frame
    covariance: Array  # (C, 3, 3)
    loop: npt.NDArray[np.bool_]  # (C,) a loop closure (else consecutive submaps)
    scan: npt.NDArray[np.int32]  # (C,) loop closures: the scan matched; -1 otherwise
    match_quality: Array  # (C,)
    active: npt.NDArray[np.bool_]  # (C,) False once dissolved
    def __len__(self) -> int: ...

class SubmapSlamTimings:
    """Processor seconds per stage of a SubmapSlam2D since construction or loading, and what it built."""
    filter: float  # s
    match: float  # s
    insert: float  # s
    closure_search: float  # s
    closure_fields: float  # s
    optimize: float  # s
    final_map: float  # s
    frontend_fields: int
    closure_fields_built: int
    closure_matches: int
    frontend_local: int
    frontend_searches: int
    def as_dict(self) -> Dict[str, float]: ...

class SubmapSlamMemory:
    """The bytes a SubmapSlam2D's large buffers hold."""
    scans: float  # bytes
    submap_grids: float  # bytes
    closure_cells: float  # bytes
    closure_fields: float  # bytes
    start_map: float  # bytes
    total: float  # bytes
    def as_dict(self) -> Dict[str, float]: ...

class GridFastSlamTimings:
    """Processor seconds per stage of a GridFastSlam since construction or loading."""
    filter: float  # s
    corrector: float  # s
    proposal: float  # s
    resample: float  # s
    map_update: float  # s
    table_copies: float  # s
    final_map: float  # s
    proposals: int
    proposal_local: int
    proposal_evaluations: int
    corrector_local: int
    corrector_searches: int
    def as_dict(self) -> Dict[str, float]: ...

class SubmapSlamSummary:
    """SubmapSlam2D.summary: counts of the run so far."""
    scans: int
    submaps: int
    matched_scans: int
    closures_searched: int
    closures_accepted: int
    closures_rejected: int
    closures_dissolved: int
    rounds: int
    optimizations: int
    final_chi2: float

class SubmapSlam2D:
    """GraphSLAM over scan-matched submaps with correlative loop closures (ch. 11.7).
    SubmapSlam2D(*, options=None, **fields): a SubmapSlamOptions, fields by keyword replacing its
    (errors name the field's path, "closures.min_match_quality")."""
    options: SubmapSlamOptions  # a copy
    num_scans: int
    num_submaps: int
    pose: Array  # (3,) the last scan's optimised pose
    scan_poses: Array  # (S, 3) optimised
    frontend_poses: Array  # (S, 3) scan matching alone
    submap_poses: Array  # (N, 3)
    timestamps: Array  # (S,)
    scan_info: Array  # (S, 5)
    constraints: SubmapConstraints
    summary: SubmapSlamSummary
    timings: SubmapSlamTimings  # processor seconds per stage (and counts) since construction or loading
    memory: SubmapSlamMemory  # bytes the large buffers hold
    start_map: Optional[OccupancyGrid2D]  # a copy of the map started from (start_from_map), or None
    def __init__(self, *, options: Optional[SubmapSlamOptions] = None,
                 frontend: IncrementalScanMatcherOptions = ..., closures: LoopClosureOptions = ...,
                 optimizer: OptimizerOptions = ..., max_rounds: int = 10) -> None: ...
    def add_scans(self, ranges: ArrayLike, beam_angles: ArrayLike, odometry: ArrayLike,
                  timestamps: ArrayLike) -> None: ...
    def copy(self) -> "SubmapSlam2D": ...
    def start_from_map(self, map: OccupancyGrid2D, initial_pose: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Before the first scan: the map is the fixed first submap (the run's frame is the map's),
        the first scan matched against it around initial_pose (x, y, theta)."""
    def finish(self) -> None: ...
    def graph(self) -> PoseGraph2D: ...
    def map(self, resolution: float = 0.0) -> OccupancyGrid2D: ...
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "SubmapSlam2D":
        """The object saved at path; ValueError naming the path for any other or damaged file."""


class GridFastSlamSummary:
    """GridFastSlam.summary: counts of the run so far."""
    scans: int
    updates: int
    resamples: int
    matched: int  # particle updates from the scan-matching proposal
    fallbacks: int  # particle updates whose match failed
    effective_sample_size: float  # after the last update, before any resampling

class TileSharing:
    """GridFastSlam.tile_sharing: map tiles held and allocated."""
    references: int  # tiles held over all particles
    distinct: int  # allocated
    bytes: int  # of the distinct tiles

class GridFastSlam:
    """Grid-based FastSLAM from a raw log (C++ fastslam/grid_fast_slam.hpp): particles with a pose,
    a log weight and their own occupancy grid (32 x 32 tiles shared copy-on-write).
    GridFastSlam(*, options=None, **fields): a GridFastSlamOptions, fields by keyword replacing its
    (errors name the field's path, "likelihood.sigma"; a num_particles or an update whose maps could
    exceed max_map_bytes raises ValueError). Results are identical for any thread count. A failed
    call changes nothing: add_scans checks every row first and undoes a batch whose row fails on
    the filter's state."""
    options: GridFastSlamOptions  # a copy
    num_scans: int
    num_particles: int
    pose: Array  # (3,) the best particle's pose
    poses: Array  # (M, 3) particle poses
    log_weights: Array  # (M,) normalised
    best_index: int
    timestamps: Array  # (S,)
    scan_poses: Array  # (S, 3) along the best particle's path
    tile_sharing: TileSharing
    summary: GridFastSlamSummary
    timings: GridFastSlamTimings  # processor seconds per stage since construction or loading
    def __init__(self, *, options: Optional[GridFastSlamOptions] = None, num_particles: int = 30,
                 proposal: str = 'scan-matching', resolution: float = 0.05, filter: ScanFilter = ...,
                 odometry: OdometryNoise = ..., likelihood: EndpointLikelihoodOptions = ...,
                 matching: ScanProposalOptions = ..., weight_scale: float = 0.03, resample_threshold: float = 0.5,
                 update: UpdateTrigger = ..., update_interval: float = 0.0,
                 corrector: IncrementalScanMatcherOptions = ..., corrected_start: bool = True, seed: int = 0,
                 threads: int = 1, max_map_bytes: float = 8589934592.0) -> None: ...
    def add_scans(self, ranges: ArrayLike, beam_angles: ArrayLike, odometry: ArrayLike,
                  timestamps: ArrayLike) -> None:
        """ranges (S, B) m, beam_angles (B,) or (S, B) rad, odometry (S, 3) sensor poses, timestamps (S,) s."""
    def copy(self) -> "GridFastSlam":
        """A deep copy: the particles' map tiles are cloned into a family of their own."""
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "GridFastSlam":
        """The object saved at path; ValueError naming the path for any other or damaged file."""
    def path(self, particle: Optional[int] = None) -> Array:
        """(S, 3) every scan's pose along a particle's path (default: the best particle's)."""
    def start_from_map(self, map: OccupancyGrid2D, initial_pose: ArrayLike = (0.0, 0.0, 0.0)) -> None:
        """Before the first scan: every particle's map starts as map (tiles shared), the first scan
        matched against it around initial_pose (x, y, theta); the run's frame is the map's."""
    start_map: Optional[OccupancyGrid2D]  # a copy of the map started from, or None
    def map(self, particle: Optional[int] = None) -> OccupancyGrid2D:
        """A particle's map as a dense grid (default: the best particle's)."""


# ---- localization (C++ localization/, core/odometry_motion_model.hpp) ----

def odometry_motion(previous: ArrayLike, current: ArrayLike) -> Tuple[float, float, float]:
    """(rot1, trans, rot2) between two odometry poses (Table 5.5 lines 2-4)."""
def sample_odometry_motion(pose: ArrayLike, previous: ArrayLike, current: ArrayLike, noise: ArrayLike, *,
                           num_samples: int = 1, seed: int = 0) -> Array:
    """(num_samples, 3) draws of Table 5.6 from pose; noise (4,) alpha1..alpha4."""
def odometry_motion_log_density(pose: ArrayLike, next_pose: ArrayLike, previous: ArrayLike, current: ArrayLike,
                                noise: ArrayLike) -> float:
    """Table 5.5: log p(next_pose | u, pose) over (rot1, trans, rot2)."""

class MclUpdate:
    """MonteCarloLocalization.update's report."""
    updated: bool
    resampled: bool
    num_particles: int
    effective_sample_size: float
    random_fraction: float

# --- options classes: generated by scripts/stub_options.py from describe(); do not edit ---
class MapManagement:
    """Ch. 10.3.3 map management of EkfSlam.update_unknown; every part off by default.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    provisional: bool
    min_observations: int
    provisional_max_std: float  # m
    provisional_max_age: int
    existence: bool
    existence_hit: float
    existence_miss: float
    existence_threshold: float
    sensor_range: float  # m
    sensor_fov: float  # rad
    def __init__(self, *, provisional: bool = False, min_observations: int = 3, provisional_max_std: float = 0.5,
                 provisional_max_age: int = 20, existence: bool = False, existence_hit: float = 1.0,
                 existence_miss: float = 0.5, existence_threshold: float = -1.0, sensor_range: float = math.inf,
                 sensor_fov: float = 6.283185307179586) -> None: ...
    def replace(self, *, provisional: bool = False, min_observations: int = 3, provisional_max_std: float = 0.5,
                provisional_max_age: int = 20, existence: bool = False, existence_hit: float = 1.0,
                existence_miss: float = 0.5, existence_threshold: float = -1.0, sensor_range: float = math.inf,
                sensor_fov: float = 6.283185307179586) -> MapManagement: ...
    def validate(self) -> None: ...
    def copy(self) -> MapManagement: ...
    def as_dict(self) -> Dict[str, Any]: ...

class MultiHypothesisOptions:
    """Beam and costs (NIS units) of MultiHypothesisEkfSlam.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    max_hypotheses: int
    max_children: int
    gate: float  # NIS
    new_landmark_cost: float  # NIS
    clutter_cost: float  # NIS
    prune_margin: float  # NIS
    detection_probability: float
    sensor_range: float  # m
    sensor_fov: float  # rad
    bearing_offset_sigma: float  # rad
    bearing_offset_correlation: float
    def __init__(self, *, max_hypotheses: int = 10, max_children: int = 4, gate: float = 0.0,
                 new_landmark_cost: float = 0.0, clutter_cost: float = 0.0, prune_margin: float = 40.0,
                 detection_probability: float = 0.0, sensor_range: float = 0.0, sensor_fov: float = 0.0,
                 bearing_offset_sigma: float = 0.0, bearing_offset_correlation: float = 0.0) -> None: ...
    def replace(self, *, max_hypotheses: int = 10, max_children: int = 4, gate: float = 0.0,
                new_landmark_cost: float = 0.0, clutter_cost: float = 0.0, prune_margin: float = 40.0,
                detection_probability: float = 0.0, sensor_range: float = 0.0, sensor_fov: float = 0.0,
                bearing_offset_sigma: float = 0.0,
                bearing_offset_correlation: float = 0.0) -> MultiHypothesisOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> MultiHypothesisOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class FastSlamOptions:
    """The options of FastSlam (Probabilistic Robotics ch. 13; Montemerlo 2002, 2003).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    num_particles: int
    version: int
    use_signatures: bool
    seed: int
    threads: int
    resample_threshold: float
    p_new: float  # m^-1 rad^-1
    outlier_density: float  # m^-1 rad^-1
    association_radius: float  # m
    joint_association: bool
    cell_size: float  # m
    negative_information: bool
    existence_hit: float
    existence_miss: float
    sensor_range: float  # m
    sensor_fov: float  # rad
    min_sightings: int
    provisional_max_age: int
    record_path: bool
    bearing_offset_sigma: float  # rad
    bearing_offset_correlation: float
    def __init__(self, *, num_particles: int = 100, version: int = 1, use_signatures: bool = False, seed: int = 0,
                 threads: int = 1, resample_threshold: float = 0.5, p_new: float = 0.01,
                 outlier_density: float = 0.0, association_radius: float = 2.0, joint_association: bool = True,
                 cell_size: float = 2.0, negative_information: bool = False, existence_hit: float = 1.0,
                 existence_miss: float = 1.0, sensor_range: float = math.inf,
                 sensor_fov: float = 6.283185307179586, min_sightings: int = 1, provisional_max_age: int = 20,
                 record_path: bool = True, bearing_offset_sigma: float = 0.0,
                 bearing_offset_correlation: float = 0.0) -> None: ...
    def replace(self, *, num_particles: int = 100, version: int = 1, use_signatures: bool = False, seed: int = 0,
                threads: int = 1, resample_threshold: float = 0.5, p_new: float = 0.01,
                outlier_density: float = 0.0, association_radius: float = 2.0, joint_association: bool = True,
                cell_size: float = 2.0, negative_information: bool = False, existence_hit: float = 1.0,
                existence_miss: float = 1.0, sensor_range: float = math.inf,
                sensor_fov: float = 6.283185307179586, min_sightings: int = 1, provisional_max_age: int = 20,
                record_path: bool = True, bearing_offset_sigma: float = 0.0,
                bearing_offset_correlation: float = 0.0) -> FastSlamOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> FastSlamOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class SparseCholeskyOptions:
    """The sparse Cholesky factorisation (CHOLMOD).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    method: str
    ordering: str
    def __init__(self, *, method: str = 'supernodal', ordering: str = 'default') -> None: ...
    def replace(self, *, method: str = 'supernodal', ordering: str = 'default') -> SparseCholeskyOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> SparseCholeskyOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class OptimizerOptions:
    """The pose-graph optimiser's options (Gauss-Newton or Levenberg-Marquardt).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    algorithm: str
    damping: str
    max_iterations: int
    relative_tolerance: float
    step_tolerance: float
    kernel: str
    kernel_width: float
    linear_solver: SparseCholeskyOptions
    def __init__(self, *, algorithm: str = 'gauss-newton', damping: str = 'marquardt', max_iterations: int = 100,
                 relative_tolerance: float = 1e-10, step_tolerance: float = 1e-10, kernel: str = 'none',
                 kernel_width: float = 1.0, linear_solver: SparseCholeskyOptions = ...) -> None: ...
    def replace(self, *, algorithm: str = 'gauss-newton', damping: str = 'marquardt', max_iterations: int = 100,
                relative_tolerance: float = 1e-10, step_tolerance: float = 1e-10, kernel: str = 'none',
                kernel_width: float = 1.0, linear_solver: SparseCholeskyOptions = ...) -> OptimizerOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> OptimizerOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class IncrementalOptions:
    """optimize_incremental's options: poses per step and each step's optimiser.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    poses_per_step: int
    step: OptimizerOptions
    def __init__(self, *, poses_per_step: int = 100, step: OptimizerOptions = ...) -> None: ...
    def replace(self, *, poses_per_step: int = 100, step: OptimizerOptions = ...) -> IncrementalOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> IncrementalOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class UpdateTrigger:
    """When a filter or scan matcher works on a scan: after this much travel or turn since it last did.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    distance: float  # m
    angle: float  # rad
    def __init__(self, *, distance: float = 0.0, angle: float = 0.0) -> None: ...
    def replace(self, *, distance: float = 0.0, angle: float = 0.0) -> UpdateTrigger: ...
    def validate(self) -> None: ...
    def copy(self) -> UpdateTrigger: ...
    def as_dict(self) -> Dict[str, Any]: ...

class ScanFilter:
    """How raw laser readings become hits, and the usable range.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    max_range: float  # m
    min_range: float  # m
    max_usable_range: float  # m
    clear_no_return: bool
    min_point_spacing: float  # m
    def __init__(self, *, max_range: float = math.inf, min_range: float = 0.0, max_usable_range: float = 30.0,
                 clear_no_return: bool = True, min_point_spacing: float = 0.0) -> None: ...
    def replace(self, *, max_range: float = math.inf, min_range: float = 0.0, max_usable_range: float = 30.0,
                clear_no_return: bool = True, min_point_spacing: float = 0.0) -> ScanFilter: ...
    def validate(self) -> None: ...
    def copy(self) -> ScanFilter: ...
    def as_dict(self) -> Dict[str, Any]: ...

class LikelihoodFieldOptions:
    """The blurred likelihood field of a grid (ch. 6.4) scans are matched against.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    sigma: float  # m
    p_rand: float
    occupied_threshold: float
    max_distance: float  # m
    def __init__(self, *, sigma: float = 0.05, p_rand: float = 0.05, occupied_threshold: float = 0.5,
                 max_distance: float = 0.0) -> None: ...
    def replace(self, *, sigma: float = 0.05, p_rand: float = 0.05, occupied_threshold: float = 0.5,
                max_distance: float = 0.0) -> LikelihoodFieldOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> LikelihoodFieldOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class SearchWindow:
    """The correlative search window around the prior pose.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    linear: float  # m
    angular: float  # rad
    angular_step: float  # rad
    def __init__(self, *, linear: float = 0.3, angular: float = 0.35, angular_step: float = 0.0) -> None: ...
    def replace(self, *, linear: float = 0.3, angular: float = 0.35,
                angular_step: float = 0.0) -> SearchWindow: ...
    def validate(self) -> None: ...
    def copy(self) -> SearchWindow: ...
    def as_dict(self) -> Dict[str, Any]: ...

class MatchOptions:
    """Correlative scan matching's window, refinement and covariance floors.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    window: SearchWindow
    refine: bool
    brute_force: bool
    min_translation_std: float  # m
    min_rotation_std: float  # rad
    min_score: float
    def __init__(self, *, window: SearchWindow = ..., refine: bool = True, brute_force: bool = False,
                 min_translation_std: float = 0.0, min_rotation_std: float = 0.0,
                 min_score: float = -math.inf) -> None: ...
    def replace(self, *, window: SearchWindow = ..., refine: bool = True, brute_force: bool = False,
                min_translation_std: float = 0.0, min_rotation_std: float = 0.0,
                min_score: float = -math.inf) -> MatchOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> MatchOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class OdometryNoise:
    """The laser SLAM classes' odometry noise: stds growing with the distance travelled and the angle turned.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    trans_per_metre: float  # m/m
    trans_per_radian: float  # m/rad
    trans_floor: float  # m
    rot_per_radian: float  # rad/rad
    rot_per_metre: float  # rad/m
    rot_floor: float  # rad
    def __init__(self, *, trans_per_metre: float = 0.1, trans_per_radian: float = 0.02, trans_floor: float = 0.01,
                 rot_per_radian: float = 0.1, rot_per_metre: float = 0.05, rot_floor: float = 0.005) -> None: ...
    def replace(self, *, trans_per_metre: float = 0.1, trans_per_radian: float = 0.02, trans_floor: float = 0.01,
                rot_per_radian: float = 0.1, rot_per_metre: float = 0.05,
                rot_floor: float = 0.005) -> OdometryNoise: ...
    def validate(self) -> None: ...
    def copy(self) -> OdometryNoise: ...
    def as_dict(self) -> Dict[str, Any]: ...

class IncrementalScanMatcherOptions:
    """The options of IncrementalScanMatcher (and SubmapSlam2D's frontend).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    resolution: float  # m
    filter: ScanFilter
    field: LikelihoodFieldOptions
    match: MatchOptions
    odometry: OdometryNoise
    use_odometry_prior: bool
    constant_velocity: bool
    match_fraction: float
    update: UpdateTrigger
    submap_distance: float  # m
    submap_scans: int
    min_match_quality: float
    warmup_scans: int
    field_refresh_distance: float  # m
    field_refresh_angle: float  # rad
    search: str
    def __init__(self, *, resolution: float = 0.05, filter: ScanFilter = ..., field: LikelihoodFieldOptions = ...,
                 match: MatchOptions = ..., odometry: OdometryNoise = ..., use_odometry_prior: bool = True,
                 constant_velocity: bool = False, match_fraction: float = 1.0, update: UpdateTrigger = ...,
                 submap_distance: float = 5.0, submap_scans: int = 0, min_match_quality: float = 0.1,
                 warmup_scans: int = 1, field_refresh_distance: float = 0.3, field_refresh_angle: float = 0.3,
                 search: str = 'fallback') -> None: ...
    def replace(self, *, resolution: float = 0.05, filter: ScanFilter = ..., field: LikelihoodFieldOptions = ...,
                match: MatchOptions = ..., odometry: OdometryNoise = ..., use_odometry_prior: bool = True,
                constant_velocity: bool = False, match_fraction: float = 1.0, update: UpdateTrigger = ...,
                submap_distance: float = 5.0, submap_scans: int = 0, min_match_quality: float = 0.1,
                warmup_scans: int = 1, field_refresh_distance: float = 0.3, field_refresh_angle: float = 0.3,
                search: str = 'fallback') -> IncrementalScanMatcherOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> IncrementalScanMatcherOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class LoopClosureOptions:
    """SubmapSlam2D's loop-closure search.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    enabled: bool
    scans_per_submap: int
    min_match_quality: float
    window_sigmas: float
    min_linear_window: float  # m
    max_linear_window: float  # m
    min_angular_window: float  # rad
    max_angular_window: float  # rad
    max_distance: float  # m
    dissolve_chi2: float
    field_cache_bytes: float  # bytes
    def __init__(self, *, enabled: bool = True, scans_per_submap: int = 3, min_match_quality: float = 0.6,
                 window_sigmas: float = 3.0, min_linear_window: float = 0.3, max_linear_window: float = 4.0,
                 min_angular_window: float = 0.1, max_angular_window: float = 0.7, max_distance: float = 20.0,
                 dissolve_chi2: float = 16.27, field_cache_bytes: float = 0.0) -> None: ...
    def replace(self, *, enabled: bool = True, scans_per_submap: int = 3, min_match_quality: float = 0.6,
                window_sigmas: float = 3.0, min_linear_window: float = 0.3, max_linear_window: float = 4.0,
                min_angular_window: float = 0.1, max_angular_window: float = 0.7, max_distance: float = 20.0,
                dissolve_chi2: float = 16.27, field_cache_bytes: float = 0.0) -> LoopClosureOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> LoopClosureOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class SubmapSlamOptions:
    """The options of SubmapSlam2D (ch. 11.7).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    frontend: IncrementalScanMatcherOptions
    closures: LoopClosureOptions
    optimizer: OptimizerOptions
    max_rounds: int
    def __init__(self, *, frontend: IncrementalScanMatcherOptions = ..., closures: LoopClosureOptions = ...,
                 optimizer: OptimizerOptions = ..., max_rounds: int = 10) -> None: ...
    def replace(self, *, frontend: IncrementalScanMatcherOptions = ..., closures: LoopClosureOptions = ...,
                optimizer: OptimizerOptions = ..., max_rounds: int = 10) -> SubmapSlamOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> SubmapSlamOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class EndpointLikelihoodOptions:
    """GridFastSlam's end-point likelihood p(z | x, m) (ch. 6.4).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    sigma: float  # m
    p_rand: float
    search_radius: float  # m
    occupied_threshold: float
    def __init__(self, *, sigma: float = 0.05, p_rand: float = 0.05, search_radius: float = 0.3,
                 occupied_threshold: float = 0.5) -> None: ...
    def replace(self, *, sigma: float = 0.05, p_rand: float = 0.05, search_radius: float = 0.3,
                occupied_threshold: float = 0.5) -> EndpointLikelihoodOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> EndpointLikelihoodOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class ScanProposalOptions:
    """GridFastSlam's scan-matching proposal (Grisetti et al. 2007): hill climb and Gaussian fit.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    linear_step: float  # m
    angular_step: float  # rad
    refinements: int
    max_moves: int
    sample_linear: float  # m
    sample_angular: float  # rad
    min_match_quality: float
    search: str
    def __init__(self, *, linear_step: float = 0.05, angular_step: float = 0.05, refinements: int = 5,
                 max_moves: int = 200, sample_linear: float = 0.01, sample_angular: float = 0.005,
                 min_match_quality: float = 0.3, search: str = 'fallback') -> None: ...
    def replace(self, *, linear_step: float = 0.05, angular_step: float = 0.05, refinements: int = 5,
                max_moves: int = 200, sample_linear: float = 0.01, sample_angular: float = 0.005,
                min_match_quality: float = 0.3, search: str = 'fallback') -> ScanProposalOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> ScanProposalOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class GridFastSlamOptions:
    """The options of GridFastSlam.
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    num_particles: int
    proposal: str
    resolution: float  # m
    filter: ScanFilter
    odometry: OdometryNoise
    likelihood: EndpointLikelihoodOptions
    matching: ScanProposalOptions
    weight_scale: float
    resample_threshold: float
    update: UpdateTrigger
    update_interval: float  # s
    corrector: IncrementalScanMatcherOptions
    corrected_start: bool
    seed: int
    threads: int
    max_map_bytes: float  # bytes
    def __init__(self, *, num_particles: int = 30, proposal: str = 'scan-matching', resolution: float = 0.05,
                 filter: ScanFilter = ..., odometry: OdometryNoise = ...,
                 likelihood: EndpointLikelihoodOptions = ..., matching: ScanProposalOptions = ...,
                 weight_scale: float = 0.03, resample_threshold: float = 0.5, update: UpdateTrigger = ...,
                 update_interval: float = 0.0, corrector: IncrementalScanMatcherOptions = ...,
                 corrected_start: bool = True, seed: int = 0, threads: int = 1,
                 max_map_bytes: float = 8589934592.0) -> None: ...
    def replace(self, *, num_particles: int = 30, proposal: str = 'scan-matching', resolution: float = 0.05,
                filter: ScanFilter = ..., odometry: OdometryNoise = ...,
                likelihood: EndpointLikelihoodOptions = ..., matching: ScanProposalOptions = ...,
                weight_scale: float = 0.03, resample_threshold: float = 0.5, update: UpdateTrigger = ...,
                update_interval: float = 0.0, corrector: IncrementalScanMatcherOptions = ...,
                corrected_start: bool = True, seed: int = 0, threads: int = 1,
                max_map_bytes: float = 8589934592.0) -> GridFastSlamOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> GridFastSlamOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...

class OdometryMotionNoise:
    """The odometry motion model's noise (Probabilistic Robotics Table 5.5 / 5.6).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    alpha1: float  # rad^2/rad^2
    alpha2: float  # rad^2/m^2
    alpha3: float  # m^2/m^2
    alpha4: float  # m^2/rad^2
    def __init__(self, *, alpha1: float = 0.2, alpha2: float = 0.2, alpha3: float = 0.2,
                 alpha4: float = 0.2) -> None: ...
    def replace(self, *, alpha1: float = 0.2, alpha2: float = 0.2, alpha3: float = 0.2,
                alpha4: float = 0.2) -> OdometryMotionNoise: ...
    def validate(self) -> None: ...
    def copy(self) -> OdometryMotionNoise: ...
    def as_dict(self) -> Dict[str, Any]: ...

class BeamMixture:
    """The beam model's mixture of range readings (Probabilistic Robotics eq. 6.4-6.12).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    z_hit: float
    z_short: float
    z_max: float
    z_rand: float
    sigma_hit: float  # m
    lambda_short: float  # 1/m
    max_range: float  # m
    def __init__(self, *, z_hit: float = 0.85, z_short: float = 0.05, z_max: float = 0.05, z_rand: float = 0.05,
                 sigma_hit: float = 0.05, lambda_short: float = 1.0, max_range: float = 5.0) -> None: ...
    def replace(self, *, z_hit: float = 0.85, z_short: float = 0.05, z_max: float = 0.05, z_rand: float = 0.05,
                sigma_hit: float = 0.05, lambda_short: float = 1.0, max_range: float = 5.0) -> BeamMixture: ...
    def validate(self) -> None: ...
    def copy(self) -> BeamMixture: ...
    def as_dict(self) -> Dict[str, Any]: ...

class MonteCarloLocalizationOptions:
    """The options of MonteCarloLocalization (Table 8.2 / 8.3, Fox 2003).
    Fields by keyword (TypeError / ValueError name the field's path); replace() a validated copy."""
    sensor_model: str
    odometry: OdometryMotionNoise
    occupied_threshold: float
    free_threshold: float
    sigma: float  # m
    p_rand: float
    beam: BeamMixture
    max_range: float  # m
    min_range: float  # m
    max_beams: int
    weight_scale: float
    min_particles: int
    max_particles: int
    kld_epsilon: float
    kld_z: float
    bin_xy: float  # m
    bin_theta: float  # rad
    alpha_slow: float
    alpha_fast: float
    recovery_ratio: float
    recovery_updates: int
    recovery_candidates: int
    resample_threshold: float
    resample_interval: int
    update: UpdateTrigger
    seed: int
    threads: int
    def __init__(self, *, sensor_model: str = 'likelihood-field', odometry: OdometryMotionNoise = ...,
                 occupied_threshold: float = 0.65, free_threshold: float = 0.25, sigma: float = 0.1,
                 p_rand: float = 0.05, beam: BeamMixture = ..., max_range: float = 30.0, min_range: float = 0.0,
                 max_beams: int = 60, weight_scale: float = 0.1, min_particles: int = 500,
                 max_particles: int = 20000, kld_epsilon: float = 0.05, kld_z: float = 2.326, bin_xy: float = 0.5,
                 bin_theta: float = 0.174532925199433, alpha_slow: float = 0.001, alpha_fast: float = 0.1,
                 recovery_ratio: float = 0.5, recovery_updates: int = 1, recovery_candidates: int = 0,
                 resample_threshold: float = 0.5, resample_interval: int = 1, update: UpdateTrigger = ...,
                 seed: int = 0, threads: int = 1) -> None: ...
    def replace(self, *, sensor_model: str = 'likelihood-field', odometry: OdometryMotionNoise = ...,
                occupied_threshold: float = 0.65, free_threshold: float = 0.25, sigma: float = 0.1,
                p_rand: float = 0.05, beam: BeamMixture = ..., max_range: float = 30.0, min_range: float = 0.0,
                max_beams: int = 60, weight_scale: float = 0.1, min_particles: int = 500,
                max_particles: int = 20000, kld_epsilon: float = 0.05, kld_z: float = 2.326, bin_xy: float = 0.5,
                bin_theta: float = 0.174532925199433, alpha_slow: float = 0.001, alpha_fast: float = 0.1,
                recovery_ratio: float = 0.5, recovery_updates: int = 1, recovery_candidates: int = 0,
                resample_threshold: float = 0.5, resample_interval: int = 1, update: UpdateTrigger = ...,
                seed: int = 0, threads: int = 1) -> MonteCarloLocalizationOptions: ...
    def validate(self) -> None: ...
    def copy(self) -> MonteCarloLocalizationOptions: ...
    def as_dict(self) -> Dict[str, Any]: ...
# --- end of the generated options classes ---


class MonteCarloLocalization:
    """Monte Carlo localization in an OccupancyGrid2D (Table 8.2 / 8.3, KLD sampling of Fox 2003)
    with the odometry motion model (Table 5.6) and the likelihood field (Table 6.3) or beam model
    (Table 6.1), its options a MonteCarloLocalizationOptions (fields by keyword replace options'
    fields). initial_pose None: global start (max_particles uniform over free cells). Results
    are identical for any thread count. A failed call changes nothing."""
    options: MonteCarloLocalizationOptions  # a copy of the options it runs with
    pose: Array  # (3,) weighted mean of the largest cluster, moved by pending odometry
    covariance: Array  # (3, 3) that cluster's covariance
    cluster_weight: float  # that cluster's share of the weight
    poses: Array  # (M, 3) every particle's pose
    weights: Array  # (M,) normalised
    num_particles: int
    num_updates: int
    w_slow: float  # augmented MCL's long-term average of the per-beam likelihood
    w_fast: float  # its short-term average
    def __init__(self, map: OccupancyGrid2D, *, options: Optional[MonteCarloLocalizationOptions] = None,
                 initial_pose: Optional[ArrayLike] = None, initial_covariance: Optional[ArrayLike] = None,
                 sensor_model: str = 'likelihood-field', odometry: OdometryMotionNoise = ...,
                 occupied_threshold: float = 0.65, free_threshold: float = 0.25, sigma: float = 0.1,
                 p_rand: float = 0.05, beam: BeamMixture = ..., max_range: float = 30.0, min_range: float = 0.0,
                 max_beams: int = 60, weight_scale: float = 0.1, min_particles: int = 500,
                 max_particles: int = 20000, kld_epsilon: float = 0.05, kld_z: float = 2.326, bin_xy: float = 0.5,
                 bin_theta: float = 0.174532925199433, alpha_slow: float = 0.001, alpha_fast: float = 0.1,
                 recovery_ratio: float = 0.5, recovery_updates: int = 1, recovery_candidates: int = 0,
                 resample_threshold: float = 0.5, resample_interval: int = 1, update: UpdateTrigger = ...,
                 seed: int = 0, threads: int = 1) -> None: ...
    def initialize_global(self) -> None:
        """Restart: max_particles uniform over the free cells."""
    def initialize_pose(self, pose: ArrayLike, covariance: ArrayLike) -> None:
        """Restart: max_particles from N(pose, covariance)."""
    def predict_odometry(self, delta: Optional[ArrayLike] = None, *, previous: Optional[ArrayLike] = None,
                         current: Optional[ArrayLike] = None) -> None:
        """Accumulate odometry: delta (3,) in the previous odometry frame, or previous= and current= poses."""
    def update(self, ranges: ArrayLike, angles: ArrayLike, *, force: bool = False) -> MclUpdate:
        """One scan; updates after update_min_d / update_min_a of travel."""
    def measurement_log_likelihood(self, pose: ArrayLike, ranges: ArrayLike, angles: ArrayLike) -> float:
        """log p(z | pose, map) of the sensor model (scan subsampled as update does)."""
    @staticmethod
    def kld_bound(k: int, epsilon: float, z: float) -> float:
        """Fox 2003's particle count for k occupied bins."""
    def copy(self) -> "MonteCarloLocalization":
        """An independent deep copy."""
    def save(self, path: Union[str, os.PathLike[str]]) -> None:
        """Writes the whole state to path (docs/file_format.md), bit for bit."""
    @staticmethod
    def load(path: Union[str, os.PathLike[str]]) -> "MonteCarloLocalization":
        """The object saved at path; ValueError naming the path for any other or damaged file."""
