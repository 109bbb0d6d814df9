"""How good is a SLAM result: the relations metric of Kümmerle et al. 2009 (``relations``), the
NEES (``consistency``), a trajectory against a corrected CARMEN log scan for scan
(``corrected``), evo's ATE and RPE (``trajectory``, their statistics in ``statistics``), a
path against reference positions such as a GPS track (``positions``), when an estimate got to
its reference and stayed (``converging``: a global localization, a kidnapping), and the scores of landmark
SLAM runs (path and map against ground truth or a survey in ``landmarks``, data association
against a dataset's labels in ``association``). Every name is importable from ``probslam.eval``.

Units: metres, radians and seconds; poses are ``(x, y, theta)`` with theta in (-pi, pi].
"""

from ..io._files import MAX_REPORTED_LINES
from .alignment import align_rigid
from .association import (association_accuracy, majority_labels, majority_truth, primary_landmarks,
                          sighting_accuracy)
from .converging import CONVERGED_HEADING, CONVERGED_POSITION, Convergence, convergence
from .corrected import (MIN_PAIRS, PAIR_TOLERANCE, CorrectedLogError, ScanPairs, corrected_log_error,
                        pair_corrected_scans)
from .consistency import NEES_SINGULAR_RTOL, SingularCovarianceError, nees
from .landmarks import LandmarkScore, MrclamScore, score_landmarks, score_mrclam, truth_positions
from .poses import interpolate_poses, relative_poses
from .positions import PositionError, position_error
from .relations import (SAME_SCAN_TIME, Relations, RelationsError, clock_offset, on_times, read_relations,
                        relations_error, relations_on_logger_time)
from .statistics import STATISTICS, error_statistics, rmse, statistics_table
from .trajectory import (ALIGNMENTS, DELTA_UNITS, MAX_TIME_DIFFERENCE, TrajectoryError, associate, ate, rpe)


__all__ = [
    "ALIGNMENTS",
    "CorrectedLogError",
    "CONVERGED_HEADING",
    "CONVERGED_POSITION",
    "DELTA_UNITS",
    "MAX_REPORTED_LINES",
    "MAX_TIME_DIFFERENCE",
    "MIN_PAIRS",
    "NEES_SINGULAR_RTOL",
    "PAIR_TOLERANCE",
    "Convergence",
    "LandmarkScore",
    "MrclamScore",
    "PositionError",
    "Relations",
    "RelationsError",
    "SAME_SCAN_TIME",
    "STATISTICS",
    "ScanPairs",
    "SingularCovarianceError",
    "TrajectoryError",
    "align_rigid",
    "associate",
    "ate",
    "association_accuracy",
    "clock_offset",
    "corrected_log_error",
    "convergence",
    "error_statistics",
    "interpolate_poses",
    "majority_labels",
    "majority_truth",
    "nees",
    "on_times",
    "pair_corrected_scans",
    "position_error",
    "primary_landmarks",
    "read_relations",
    "relations_on_logger_time",
    "relations_error",
    "relative_poses",
    "rmse",
    "rpe",
    "score_landmarks",
    "score_mrclam",
    "statistics_table",
    "sighting_accuracy",
    "truth_positions",
]
