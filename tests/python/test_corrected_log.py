"""A trajectory against a corrected CARMEN log, scan for scan (probslam.eval.corrected): each
corrected scan is paired with the raw scan of identical ranges and logger time within 0.01 s,
on hand-built logs whose raw times go back and whose ranges repeat; the errors after the rigid
alignment; and `eval`'s pipeline with the raw log (EvaluationOptions.raw_log), as `probslam batch`
scores a slam run."""

import math
import warnings

import numpy as np
import pytest

from probslam import eval as ev
from probslam import io
from probslam.pipelines import EvaluationOptions, evaluate_trajectory

#: Raw scans: (ranges, logger time). Times go back (0.5 then 0.4, as the raw Intel log's do);
#: scans 1 and 3 have the same ranges 5 ms apart; scan 4 is one beam shorter (NaN-padded).
RAW = [((1.0, 2.0, 3.0), 0.0), ((2.0, 2.0, 2.0), 0.5), ((3.0, 1.0, 2.0), 0.4), ((2.0, 2.0, 2.0), 0.505),
       ((1.5, 2.5), 1.0), ((4.0, 4.0, 4.0), 1.015)]
#: Corrected scans: (ranges, logger time as the corrected log prints it) and what they pair with:
#: 0 -> raw 0; 1 has two raw twins within 0.01 s (ambiguous, left out); 2 -> raw 2 (the earlier
#: time after a later one); 3 has raw 4's ranges 0.02 s away (too far) and raw 5 is nearest in
#: time with other ranges (not a pair); 4 has raw 1's ranges 0.2 s away; 5 -> raw 5.
CORRECTED = [((1.0, 2.0, 3.0), 0.003), ((2.0, 2.0, 2.0), 0.502), ((3.0, 1.0, 2.0), 0.4), ((1.5, 2.5), 1.02),
             ((2.0, 2.0, 2.0), 0.7), ((4.0, 4.0, 4.0), 1.012)]
PAIRED_RAW, PAIRED_CORRECTED = [0, 2, 5], [0, 2, 5]
#: Laser poses of the corrected scans, and the rigid motion the estimate is in (a frame of its own).
CORRECTED_POSES = np.array([[0.0, 0.0, 0.1], [1.0, 0.0, 0.2], [1.0, 1.0, 1.5], [2.0, 1.0, -3.0], [0.5, 2.0, 3.1],
                            [2.0, 3.0, -3.1]])
TURN, SHIFT = 0.7, np.array([5.0, -2.0])
#: Heading error put on raw scan 5's estimate (rad): the position errors stay zero.
HEADING_ERROR = 0.25
#: Round-off of an alignment of exact data (m, rad).
EXACT = 1e-9


def _write_log(path, scans, poses):
    lines = []
    for (ranges, t), (x, y, theta) in zip(scans, poses):
        lines.append(f"FLASER {len(ranges)} {' '.join(map(str, ranges))} {x} {y} {theta} {x} {y} {theta} "
                     f"{t + 100.0:.6f} host {t:.6f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def _estimate():
    """The raw scans' poses in the estimate's frame: the corrected ones moved by (TURN, SHIFT)
    (a corrected pose for each raw scan, those without one anywhere), raw 5's heading off."""
    poses = np.zeros((len(RAW), 3))
    poses[PAIRED_RAW] = CORRECTED_POSES[PAIRED_CORRECTED]
    c, s = math.cos(TURN), math.sin(TURN)
    moved = poses[:, :2] @ np.array([[c, -s], [s, c]]).T + SHIFT
    theta = np.arctan2(np.sin(poses[:, 2] + TURN), np.cos(poses[:, 2] + TURN))
    theta[5] += HEADING_ERROR
    return np.column_stack([moved, theta])


@pytest.fixture
def logs(tmp_path):
    raw = _write_log(tmp_path / "raw.log", RAW, np.zeros((len(RAW), 3)))
    corrected = _write_log(tmp_path / "corrected.log", CORRECTED, CORRECTED_POSES)
    return raw, corrected


def test_a_corrected_scan_pairs_with_the_one_raw_scan_of_its_ranges_and_time(logs):
    raw, corrected = (io.read_carmen_log(p).scans for p in logs)
    pairs = ev.pair_corrected_scans(raw, corrected)
    np.testing.assert_array_equal(pairs.raw_indices, PAIRED_RAW)
    np.testing.assert_array_equal(pairs.corrected_indices, PAIRED_CORRECTED)
    assert (pairs.corrected, pairs.ambiguous, len(pairs)) == (6, 1, 3)
    assert str(pairs) == "3/6 corrected scans paired, 1 ambiguous left out"
    # Independently, by brute force: every raw scan of equal ranges (NaN padding equal) within 0.01 s.
    for k in range(len(corrected)):
        twins = [i for i in range(len(raw)) if np.array_equal(raw.ranges[i], corrected.ranges[k], equal_nan=True)
                 and abs(raw.timestamps[i] - corrected.timestamps[k]) <= ev.PAIR_TOLERANCE]
        assert (twins == [pairs.raw_indices[list(pairs.corrected_indices).index(k)]]) if len(twins) == 1 else \
            k not in pairs.corrected_indices
    # A wider tolerance pairs corrected scan 3 with raw 4 (0.02 s apart).
    assert 3 in ev.pair_corrected_scans(raw, corrected, tolerance=0.03).corrected_indices
    with pytest.raises(ValueError, match="^tolerance must be finite and > 0"):
        ev.pair_corrected_scans(raw, corrected, tolerance=0.0)
    with pytest.raises(TypeError, match="^corrected: expected LaserScans"):
        ev.pair_corrected_scans(raw, CORRECTED_POSES)


def test_the_errors_are_taken_after_the_rigid_alignment(logs):
    raw, corrected = (io.read_carmen_log(p).scans for p in logs)
    e = ev.corrected_log_error(_estimate(), raw, corrected)
    assert e.matched == 3 and e.outside == 0
    np.testing.assert_allclose(e.errors, 0.0, atol=EXACT)
    np.testing.assert_allclose(e.heading_errors, [0.0, 0.0, HEADING_ERROR], atol=EXACT)
    np.testing.assert_allclose(math.atan2(e.rotation[1, 0], e.rotation[0, 0]), -TURN, atol=EXACT)
    assert e.heading_statistics_deg["max"] == pytest.approx(math.degrees(HEADING_ERROR))
    # Poses for the first five raw scans only: raw 5's pair is past them, two are left: too few.
    with pytest.raises(ValueError, match=r"^corrected: 3/6 corrected scans paired, 1 ambiguous left out, 2 of them"):
        ev.corrected_log_error(_estimate()[:5], raw, corrected)
    with pytest.raises(ValueError, match="^poses: 7 rows, but the raw log has 6 scans"):
        ev.corrected_log_error(np.zeros((7, 3)), raw, corrected)


def test_eval_with_the_raw_log_pairs_scan_for_scan(logs, tmp_path):
    raw, corrected = logs
    times = io.read_carmen_log(raw).scans.timestamps
    estimate = io.write_trajectory(times, _estimate(), tmp_path / "est.tum")[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the raw times go back, and the estimate's with them
        run = evaluate_trajectory(estimate, corrected, EvaluationOptions(raw_log=str(raw)))
        assert isinstance(run.result, ev.CorrectedLogError) and run.result.matched == 3
        np.testing.assert_allclose(run.result.heading_errors, [0.0, 0.0, HEADING_ERROR], atol=EXACT)
        assert "3/6 corrected scans paired, 1 ambiguous left out with " in run.summary()
        # Without it: nearest in time (evo's association), which pairs raw 4 with corrected 3.
        assert evaluate_trajectory(estimate, corrected).result.matched == 5
        # An estimate whose rows are not the raw log's scans is refused, naming both.
        shuffled = io.write_trajectory(times[::-1], _estimate(), tmp_path / "shuffled.tum")[0]
        with pytest.raises(ValueError, match=r"shuffled.tum: its rows are not .*raw.log's scans in order \(row 0"):
            evaluate_trajectory(shuffled, corrected, EvaluationOptions(raw_log=str(raw)))
        with pytest.raises(ValueError, match="^rpe: with raw_log a corrected log is compared scan for scan"):
            evaluate_trajectory(estimate, corrected, EvaluationOptions(raw_log=str(raw), rpe=True))
