"""EKF SLAM (ch. 10): the Python face of the C++ filter."""

from __future__ import annotations

from typing import NamedTuple, Optional

import numpy as np

from . import _core
from ._args import require_integer
from ._core import Association, Landmarks, MapManagement, chi_square_quantile

#: Association gate: the chi-square quantile at this probability, with the measurement's
#: degrees of freedom, is the default Mahalanobis threshold alpha of Table 10.2.
DEFAULT_ASSOCIATION_PROBABILITY = 0.99
#: A measurement creates a landmark only when even this quantile rejects every candidate; those
#: in between are discarded as ambiguous (otherwise the 1% of true re-sightings beyond alpha
#: would each spawn a duplicate landmark).
DEFAULT_NEW_LANDMARK_PROBABILITY = 1.0 - 1e-6

#: ``update_unknown``'s association methods by name.
ASSOCIATIONS = {"ml": Association.MAXIMUM_LIKELIHOOD, "jcbb": Association.JOINT_COMPATIBILITY}


class UpdateResult(NamedTuple):
    """What EkfSlam.update did with each of its k measurements."""

    nis: np.ndarray  # (k,) normalised innovation squared, NaN for first sightings
    used: np.ndarray  # (k,) bool, False where the gate rejected the measurement


class HypothesisUpdate(NamedTuple):
    """What MultiHypothesisEkfSlam.update did with a scan of k measurements."""

    ids: np.ndarray  # (k,) the best filter's landmark id per measurement, -1 for clutter
    num_hypotheses: int  # filters in the beam after the scan
    cost: float  # the best filter's cost, NIS units


class AssociationResult(NamedTuple):
    """What EkfSlam.update_unknown did with each of its k measurements."""

    ids: np.ndarray  # (k,) landmark id used or created, -1 if none
    mahalanobis: np.ndarray  # (k,) smallest pi over the candidates
    outcome: np.ndarray  # (k,) 0 associated, 1 new landmark, 2 provisional, 3 discarded
    removed: np.ndarray  # ids dropped by the existence test

    ASSOCIATED, NEW_LANDMARK, PROVISIONAL, DISCARDED = 0, 1, 2, 3


def _number(value, name: str) -> float:
    """value as a float; TypeError naming the argument for anything that is not a real number."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name} must be a number, got {type(value).__name__}")
    return float(value)


def _count(value, name: str) -> int:
    return require_integer(value, name, -2**31, 2**31 - 1)


def _landmark_id(value) -> int:
    """A landmark id: an integer within the C++ side's 64-bit range, named ``id`` in errors."""
    return require_integer(value, "id", -2**63, 2**63 - 1)


def _flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be a bool, got {type(value).__name__}")
    return bool(value)


class EkfSlam:
    """Online SLAM with the extended Kalman filter (Tables 10.1, 10.2).

    State (eq. 10.7): ``(x, y, theta, m1x, m1y[, s1], ...)``. The signatures s_j are kept apart
    from the dense ``mean`` and ``covariance`` (``signatures``: each one's mean and variance): a
    signature is measured directly and starts uncorrelated with the rest, so its cross
    covariances in the full state are zero, and the O(n^2) update passes over a smaller matrix.

    Args:
        motion_noise: (3, 3) pose-space covariance R_t added as F_x^T R_t F_x, or (2, 2)
            control-space covariance M of (v [m/s], w [rad/s]) mapped through dg/du.
        measurement_noise: Q_t, (2, 2) variances of (range [m^2], bearing [rad^2]), or (3, 3)
            with the signature's variance when ``use_signatures`` (the signature uncorrelated
            with range and bearing: zero (0, 2) and (1, 2) entries).

    Keyword options:
        use_signatures: measurements ``(range, bearing, signature)`` and landmarks with a
            signature (False: ``(range, bearing)``), as ``FastSlam``'s.
        initial_pose: (3,) ``(x, y, theta)``; initial_pose_cov: (3, 3), zeros by default.
        map_management: ch. 10.3.3 options (``MapManagement``) for ``update_unknown``.
        gate_distance: metres; association candidates are the landmarks within it of where
            the measurement places its landmark.

    Reliability (docs/reliability.md): every call validates all its input first and raises ValueError or
    TypeError naming the argument, with the filter unchanged; a call whose result would not be
    finite raises too, and changes nothing. Named limits (``ekf_slam.hpp``): coordinates,
    ranges, signatures and one motion's length within 1e9 m (``kEkfMaxCoordinate``); noise
    entries within 1e18 (``kEkfMaxVariance``); a state of at most 16384 dimensions
    (``kEkfMaxStateDimension``); landmark ids in [0, 2^62]. Concurrent calls from several
    threads are serialised by a per-filter lock; ``mean`` and ``covariance`` are views that no
    lock guards (copy them while other threads update the filter).
    """

    def __init__(self, motion_noise, measurement_noise, *, use_signatures: bool = False, initial_pose=(0.0, 0.0, 0.0),
                 initial_pose_cov=None, map_management: Optional[MapManagement] = None, gate_distance: float = 5.0):
        if map_management is not None and not isinstance(map_management, MapManagement):
            raise TypeError(f"map_management must be a MapManagement, got {type(map_management).__name__}")
        cov = np.zeros((3, 3)) if initial_pose_cov is None else initial_pose_cov
        f = _core._EkfSlam(motion_noise, measurement_noise, _flag(use_signatures, "use_signatures"), initial_pose, cov)
        if map_management is not None:
            f.map_management = map_management
        f.gate_distance = _number(gate_distance, "gate_distance")
        self._f = f

    def __repr__(self) -> str:
        # The C++ filter formats it (bindings/ekf.cpp); shown under this class's name.
        return "<EkfSlam: " + repr(self._f).split(": ", 1)[1]

    def copy(self) -> "EkfSlam":
        """An independent copy of the filter: state, map, ids, options."""
        c = object.__new__(type(self))
        c._f = self._f.copy()
        return c

    __copy__ = copy

    def __deepcopy__(self, memo) -> "EkfSlam":
        return self.copy()

    def save(self, path) -> None:
        """Writes the whole filter to path (docs/file_format.md), bit for bit: ``EkfSlam.load(path)``
        equals this filter and continues exactly as it would."""
        self._f.save(path)

    @classmethod
    def load(cls, path) -> "EkfSlam":
        """The filter saved at path; ValueError naming the path for any other or damaged file."""
        e = object.__new__(cls)
        e._f = _core._EkfSlam.load(path)
        return e

    def __getstate__(self):
        return {"_f": self._f}

    def __setstate__(self, state) -> None:
        self._f = state["_f"]

    # --- state -------------------------------------------------------------------------
    @property
    def mean(self) -> np.ndarray:
        """(D,) zero-copy view of the dense state (pose, then each landmark's x, y); valid until
        the next call that adds a landmark."""
        return self._f.mean

    @property
    def covariance(self) -> np.ndarray:
        """(D, D) zero-copy view of the covariance (symmetric); same validity as ``mean``."""
        return self._f.covariance

    @property
    def signatures(self) -> np.ndarray:
        """(N, 2) each landmark's signature mean and variance, in state order, a copy ((0, 2)
        without signatures). The filter keeps them apart from ``mean`` and ``covariance``: a
        signature is measured directly and uncorrelated with the pose and the positions, so its
        cross covariances in the full state would be zero."""
        return self._f.signatures

    @property
    def pose(self) -> np.ndarray:
        """(3,) mean pose (x m, y m, theta rad), a copy."""
        return self._f.pose

    def landmarks(self) -> Landmarks:
        """The map as ``Landmarks``: ids (N,) int64, means (N, 2) m, covariances (N, 2, 2) m^2
        (the position part, without a signature), in state order."""
        return self._f.landmarks()

    @property
    def num_landmarks(self) -> int:
        """Landmarks in the state."""
        return self._f.num_landmarks

    @property
    def num_provisional(self) -> int:
        """Landmarks waiting on the provisional list (ch. 10.3.3)."""
        return self._f.num_provisional

    @property
    def state_dim(self) -> int:
        """Length of the dense state: 3 + 2 per landmark (signatures apart, see ``signatures``)."""
        return self._f.state_dim

    @property
    def use_signatures(self) -> bool:
        """Whether landmarks and measurements carry a signature (3 values instead of 2)."""
        return self._f.landmark_dim == 3

    @property
    def gate_distance(self) -> float:
        """Association candidates of update_unknown: the landmarks within this distance (m) of
        where a measurement places its landmark, plus three standard deviations. Settable, checked
        as the constructor checks it (a name not a property would be a silent new attribute)."""
        return self._f.gate_distance

    @gate_distance.setter
    def gate_distance(self, metres: float) -> None:
        self._f.gate_distance = _number(metres, "gate_distance")

    @property
    def map_management(self) -> MapManagement:
        """Ch. 10.3.3 options of update_unknown (a copy; assign a MapManagement to change them)."""
        return self._f.map_management

    @map_management.setter
    def map_management(self, value: MapManagement) -> None:
        if not isinstance(value, MapManagement):
            raise TypeError(f"map_management must be a MapManagement, got {type(value).__name__}")
        self._f.map_management = value

    def landmark(self, id: int) -> np.ndarray:
        """Mean of landmark id: (x, y) m, or (x, y, signature)."""
        return self._f.landmark(_landmark_id(id))

    def landmark_covariance(self, id: int) -> np.ndarray:
        """(2, 2) (or (3, 3) with signatures) covariance of landmark ``id``."""
        return self._f.landmark_covariance(_landmark_id(id))

    def existence(self, id: int) -> float:
        """Existence log-odds o_j of landmark ``id`` (ch. 10.3.3)."""
        return self._f.existence(_landmark_id(id))

    def remove_landmark(self, id: int) -> None:
        """Marginalises landmark id out of the state."""
        self._f.remove_landmark(_landmark_id(id))

    # --- filter ------------------------------------------------------------------------
    def predict(self, v: float, w: float, dt: float, noise=None) -> None:
        """Table 10.1 lines 2-5 (v m/s, w rad/s, dt s > 0); O(N). ``noise`` overrides the
        motion noise for this call ((3, 3) pose space or (2, 2) control space)."""
        self._f.predict(_number(v, "v"), _number(w, "w"), _number(dt, "dt"), noise)

    def predict_odometry(self, delta, noise) -> None:
        """x <- x (+) delta for odometry given as a relative pose (3,) with (3, 3) covariance."""
        self._f.predict_odometry(delta, noise)

    def predict_odometry_batch(self, deltas, noises) -> np.ndarray:
        """``predict_odometry(deltas[k], noises[k])`` for every row of deltas (K, 3) with noises
        (K, 3, 3), in one call; returns the pose after each step (K, 3). The landmarks' cross
        covariances move once, by the steps' composed Jacobian: O(K + N) instead of O(K N), equal
        to K calls up to rounding."""
        return self._f.predict_odometry_batch(deltas, noises)

    def update(self, z, ids, gate: Optional[float] = None) -> UpdateResult:
        """Known correspondences: z (k, 2) ``(r, phi)`` or (k, 3) ``(r, phi, s)``, ids (k,) ints.

        Measurements are applied one after another; a landmark seen for the first time is
        added by state augmentation. With ``gate``, measurements whose NIS exceeds it (e.g. a
        chi-square quantile) are skipped as outliers.
        """
        ids_array = np.asarray(ids)
        if ids_array.size and ids_array.dtype.kind not in "iu":
            raise TypeError(f"ids must be integers, got dtype {ids_array.dtype}")
        nis, used = self._f.update(z, ids_array, np.inf if gate is None else _number(gate, "gate"))
        return UpdateResult(nis, used)

    def pairing_likelihood(self, z, id: int):
        """Table 10.1 lines 12-16 for one measurement z (2,) or (3,) against landmark ``id``,
        without updating: ``(nis, log det(2 pi S))``, whose sum is -2 log N(nu; 0, S)."""
        return self._f.pairing_likelihood(z, id)

    def update_unknown(self, z, alpha: Optional[float] = None, alpha_new: Optional[float] = None,
                       association: str = "ml") -> AssociationResult:
        """Table 10.2: unknown correspondences for one scan z (k, 2) or (k, 3).

        ``alpha`` (default: chi-square quantile 0.99) is the Mahalanobis threshold below which a
        measurement may join a landmark; each landmark takes at most one measurement of a scan.
        ``association``: ``"ml"`` pairs the smallest distances first (Table 10.2); ``"jcbb"``
        takes the jointly compatible pairing of the whole scan with the most pairs (joint
        compatibility branch and bound, Neira & Tardos 2001), its joint gates the chi-square
        quantiles at alpha's probability, which tells neighbouring landmarks apart when several
        are seen at once. An unpaired measurement creates a landmark when its distance exceeds
        ``alpha_new`` (default: quantile 1 - 1e-6) for every landmark not paired with another
        measurement of the scan; otherwise it is discarded as ambiguous.
        """
        if not isinstance(association, str):
            raise TypeError(f"association must be a string, got {type(association).__name__}")
        if association not in ASSOCIATIONS:
            raise ValueError(f"association must be one of {sorted(ASSOCIATIONS)}, got {association!r}")
        alpha = None if alpha is None else _number(alpha, "alpha")
        alpha_new = None if alpha_new is None else _number(alpha_new, "alpha_new")
        d = self._f.landmark_dim
        alpha = chi_square_quantile(DEFAULT_ASSOCIATION_PROBABILITY, d) if alpha is None else alpha
        if alpha_new is None:
            alpha_new = max(alpha, chi_square_quantile(DEFAULT_NEW_LANDMARK_PROBABILITY, d))
        ids, pi, outcome, removed = self._f.update_unknown(z, alpha, alpha_new, ASSOCIATIONS[association])
        return AssociationResult(ids.astype(np.int64), pi, outcome.astype(np.int8), np.asarray(removed, np.int64))


class MultiHypothesisEkfSlam:
    """EKF SLAM with unknown correspondences decided over several scans: a beam of ``EkfSlam``
    filters, each one history of assignments (track-splitting multiple-hypothesis tracking).

    Every scan, each filter branches into its ``max_children`` cheapest assignments (each
    measurement to a gated landmark, a new landmark, or clutter; a landmark takes one
    measurement per scan), applied one measurement after another; the ``max_hypotheses``
    cheapest children within ``prune_margin`` of the best survive. Costs are -2 log-likelihoods
    in NIS units: a pairing costs NIS + log det(S Q^-1), a new landmark ``new_landmark_cost``
    (default: chi-square quantile 1 - 1e-6), clutter ``clutter_cost`` (quantile 1 - 4.5e-5, 20.0 for 2 dof).
    A pairing that later scans contradict, such as a robot that lost its heading during a
    stretch without landmarks pairing its first sighting with the wrong landmark, or a first
    sighting that was an outlier, is overtaken by the branch that did not make it.

    Args:
        ekf: the starting filter (copied): noise, pose, any landmarks already mapped.
        options: a ``MultiHypothesisOptions`` (default: its defaults); further keyword options
            set single fields of it by name (``max_hypotheses=20``). Its fields, with units and limits, are
            in ``help(MultiHypothesisOptions)``: the beam (max_hypotheses, max_children), the
            costs in NIS units (gate, new_landmark_cost and clutter_cost, whose default 0 stands
            for the chi-square quantiles 0.999, 1 - 1e-6 and 1 - 4.5e-5 of the measurement's
            dimension; prune_margin), missed detections (detection_probability P_D of a
            landmark inside the sensor's field, sensor_range m and sensor_fov rad centred
            ahead: a landmark in view costs -2 ln P_D when a measurement goes to it and
            -2 ln(1 - P_D) when none does, so alternatives holding landmarks never seen again
            fall behind), and a bearing offset shared by a scan's measurements
            (bearing_offset_sigma rad, bearing_offset_correlation: its AR(1) from scan to scan;
            each filter carries the offset's mean, variance and covariance with its state, and
            ``ekf``'s measurement noise is the part not shared).

    A value out of range raises ValueError naming the field; ``predict`` and ``update`` change
    every filter of the beam or, when they raise, none. A scan whose children would hold more
    than 4 GiB of covariance is refused.
    """

    def __init__(self, ekf: EkfSlam, *, options: Optional[_core.MultiHypothesisOptions] = None, **fields):
        if not isinstance(ekf, EkfSlam):
            raise TypeError(f"ekf must be an EkfSlam, got {type(ekf).__name__}")
        if options is not None and not isinstance(options, _core.MultiHypothesisOptions):
            raise TypeError(f"options must be a MultiHypothesisOptions, got {type(options).__name__}")
        o = (options or _core.MultiHypothesisOptions()).replace(**fields)
        self._m = _core._MultiHypothesisEkfSlam(ekf._f, o)

    def __repr__(self) -> str:
        return "<MultiHypothesisEkfSlam: " + repr(self._m).split(": ", 1)[1]

    def predict(self, v: float, w: float, dt: float, noise=None) -> None:
        """Table 10.1 lines 2-5 on every filter (see ``EkfSlam.predict``)."""
        self._m.predict(_number(v, "v"), _number(w, "w"), _number(dt, "dt"), noise)

    def update(self, z) -> HypothesisUpdate:
        """One scan z (k, 2) or (k, 3). Returns the best filter's landmark id per measurement
        (k,), -1 for clutter (later scans may still change the best filter's earlier choices),
        the beam's size and the best filter's cost after the scan."""
        ids = self._m.update(z).astype(np.int64)
        return HypothesisUpdate(ids, self._m.num_hypotheses, self._m.total_cost)

    def save(self, path) -> None:
        """Writes the whole beam to path (docs/file_format.md), bit for bit:
        ``MultiHypothesisEkfSlam.load(path)`` equals it and continues exactly as it would."""
        self._m.save(path)

    @classmethod
    def load(cls, path) -> "MultiHypothesisEkfSlam":
        """The beam saved at path; ValueError naming the path for any other or damaged file."""
        m = object.__new__(cls)
        m._m = _core._MultiHypothesisEkfSlam.load(path)
        return m

    def copy(self) -> "MultiHypothesisEkfSlam":
        """An independent deep copy: the same calls then give both the same results."""
        m = object.__new__(type(self))
        m._m = self._m.copy()
        return m

    def __getstate__(self):
        return {"_m": self._m}

    def __setstate__(self, state) -> None:
        self._m = state["_m"]

    @property
    def best(self) -> EkfSlam:
        """A copy of the cheapest filter."""
        e = object.__new__(EkfSlam)
        e._f = self._m.best
        return e

    @property
    def pose(self) -> np.ndarray:
        """(3,) the best filter's pose, without copying the filter."""
        return self._m.pose

    @property
    def num_hypotheses(self) -> int:
        """Hypotheses (filters) in the beam."""
        return self._m.num_hypotheses

    @property
    def costs(self) -> np.ndarray:
        """Cost of each filter above the best's, ascending (NIS units)."""
        return self._m.costs

    @property
    def total_cost(self) -> float:
        """The best filter's whole cost (NIS units): its pairings, new landmarks and clutter."""
        return self._m.total_cost

    @property
    def options(self):
        """The MultiHypothesisOptions in use (a copy)."""
        return self._m.options

    def history(self) -> list:
        """The best filter's assignment of every non-empty scan so far: (k,) ids, -1 clutter."""
        return [a.astype(np.int64) for a in self._m.history()]
