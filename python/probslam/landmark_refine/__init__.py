"""GraphSLAM's correspondence test (Probabilistic Robotics ch. 11.6, Tables 11.8 and 11.9) as a
refinement of any landmark filter's result: the filter's poses, sightings and landmark labels
start a GraphSLAM over all sightings (pose vertices only where sightings were taken, the
odometry composed between them), which then, round by round:

0. (first round, ``estimate_noise``) rescales the odometry, range and bearing noise to the
   residuals of the optimum by variance component estimation: a filter's noise is set for the
   filter, often several times the sensor's, and a test against it sees nothing;
1. tests landmark pairs for identity with the full posterior: the joint (4, 4) marginal of the
   pair, cross-covariance included (``graph.joint_marginal_covariances``), gives Table 11.8's
   difference Delta = m_j - m_k and its covariance; a pair merges when the Mahalanobis distance
   of Delta from 0 is within the chi-square quantile ``MERGE_PROBABILITY`` (2 dof), unless the two
   were seen in one scan (one scan sees distinct landmarks, ch. 11.6's refinement); groups join
   only when every pair across them passed;
2. (the undo of 11.6) tests each sighting against its own landmark: the leave-one-out innovation
   of the sighting, its residual at the optimum weighed by the residual's covariance
   Q - H Sigma H^T (equal to the innovation of the sighting against the posterior of all the
   other sightings); the sightings beyond the split gate leave by backward elimination (worst
   first, the posterior updated after each) for the most likely other landmark within the gate,
   else for a new landmark (``new_landmarks``) or none (UNASSIGNED);
3. moves each sighting that another landmark explains better than its own (maximum likelihood,
   each under the posterior of the others; UNASSIGNED sightings join the most likely landmark
   within the gate);

a round makes the first kind of change that has any (merges, else splits, else moves),
optimises again, and the refinement stops when a round changes nothing, or at
``max_iterations``. Every test is exact for the linearised problem at the round's minimum; the
tests in tests/python/test_landmark_refine.py repeat each round by brute force on the dense
inverse.

Units: metres, radians. Poses (x, y, theta) with theta wrapped to (-pi, pi]. Sightings are
range-bearing; the graph holds each as the point in the pose's frame with the information of its
range-bearing noise carried through the polar-to-Cartesian Jacobian (GraphSLAM's linearisation;
the tests measure what the Cartesian form changes against exact range-bearing residuals: 0.02
standard deviations of a landmark).

``refine_landmarks`` works on arrays; each dataset builds them from a filter run over it
(``probslam.datasets.refinement_input``, with ``run_labels`` and ``poses_at_nodes`` from here),
and ``probslam.refine_run`` does both: the one entry point for a run.
``sighting_accuracy`` and ``majority_truth`` (from ``probslam.eval``) score a labelling against
the dataset's ids.

Modules: ``problem`` (the linearised sightings and the graph), ``arguments`` (the input's
checks), ``gates``, ``noise`` (step 0), ``merges`` (step 1), ``sightings`` (the leave-one-out
statistics), ``splits`` (step 2), ``moves`` (step 3), ``refine`` (the rounds), ``results``, and
``runs`` (the arrays from a filter run over a dataset).
"""

from ..eval import majority_truth, sighting_accuracy
from .gates import MERGE_PROBABILITY, SPLIT_RUN_PROBABILITY, merge_gate, split_gate
from .moves import REASSOCIATION_MARGIN, REASSOCIATION_ODDS
from .noise import NOISE_MAX_ITERATIONS, NOISE_TOLERANCE
from .problem import (COVARIANCE_CONDITION_FLOOR, MINIMUM_DECREASE, MINIMUM_STEP, NOISE_OPTIMIZE_TOLERANCE,
                      UNASSIGNED, polar_to_point)
from .refine import MAX_ITERATIONS, check_options, refine_landmarks
from .results import LandmarkRefinement, Merge, RefinementRound, Split
from .runs import (ODOMETRY_COVARIANCE_FLOOR, RefinementInput, RunRefinement, compose_increments, floor_covariances,
                   poses_at_nodes, run_labels)
from .sightings import LEAVE_ONE_OUT_RANK_TOLERANCE
from .splits import MAX_SUSPECTS_PER_ROUND



__all__ = ["COVARIANCE_CONDITION_FLOOR", "LEAVE_ONE_OUT_RANK_TOLERANCE", "LandmarkRefinement", "MAX_ITERATIONS",
           "MAX_SUSPECTS_PER_ROUND", "MERGE_PROBABILITY", "MINIMUM_DECREASE", "MINIMUM_STEP", "Merge",
           "NOISE_MAX_ITERATIONS", "NOISE_OPTIMIZE_TOLERANCE", "NOISE_TOLERANCE", "ODOMETRY_COVARIANCE_FLOOR",
           "REASSOCIATION_MARGIN", "REASSOCIATION_ODDS", "RefinementInput", "RefinementRound", "RunRefinement",
           "SPLIT_RUN_PROBABILITY", "Split", "UNASSIGNED", "check_options", "compose_increments", "floor_covariances",
           "majority_truth", "merge_gate", "polar_to_point", "poses_at_nodes", "refine_landmarks", "run_labels",
           "sighting_accuracy", "split_gate"]
