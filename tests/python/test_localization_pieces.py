"""Localization on pieces of a log and against a reference: the convergence criterion
(eval.convergence) on hand-made trajectory pairs, a piece of log time (span_end) against its
definition as a loop, the splice (a kidnapped robot) against its definition on a small synthetic
log, and the batch localize kind's row for a segment and a splice of the bundled Intel loop against
the same runs made by hand on the library."""

import math

import numpy as np
import pytest

from probslam import data, geometry, io
from probslam import eval as ev
from probslam.localization import default_options, localize
from probslam.pipelines import CLOCK_JUMP, LogPiece, localize_log, span_end, splice

# --- the convergence criterion ---------------------------------------------------------------------

TIMES = np.arange(8, dtype=float)
#: A straight reference along x, one metre a second; the odometry is that path (its travel: 1 m a step).
REFERENCE = np.column_stack([TIMES, np.zeros(8), np.zeros(8)])


def _estimate(offsets, headings=None):
    """The reference moved sideways by ``offsets`` (m), turned by ``headings`` (rad)."""
    est = REFERENCE.copy()
    est[:, 1] += offsets
    if headings is not None:
        est[:, 2] = headings
    return est


def test_convergence_is_the_first_pose_right_to_the_end():
    est = _estimate([3.0, 2.0, 1.0, 0.6, 0.1, 0.2, 0.0, 0.3])
    c = ev.convergence(TIMES, est, TIMES, REFERENCE, odometry=REFERENCE)
    assert c.converged and c.index == 4 and c.time == 4.0 and c.travel == pytest.approx(4.0)
    np.testing.assert_allclose(c.position_errors, [3.0, 2.0, 1.0, 0.6, 0.1, 0.2, 0.0, 0.3])
    # Right from the start: index 0, no time, no travel.
    c = ev.convergence(TIMES, REFERENCE, TIMES, REFERENCE, odometry=REFERENCE)
    assert (c.index, c.time, c.travel) == (0, 0.0, 0.0)


def test_convergence_then_lost_or_never_is_not_converged():
    lost = _estimate([3.0, 0.1, 0.1, 0.1, 0.1, 0.1, 2.0, 2.0])
    never = _estimate(np.full(8, 3.0))
    turned = _estimate(np.zeros(8), [0.0] * 7 + [ev.CONVERGED_HEADING + 0.01])  # the last heading wrong
    for est in (lost, never, turned):
        c = ev.convergence(TIMES, est, TIMES, REFERENCE, odometry=REFERENCE)
        assert not c.converged and (c.index, c.time, c.travel) == (None, None, None)
    # The tolerances are strict: an error of exactly CONVERGED_POSITION is wrong.
    edge = _estimate([0.0] * 7 + [ev.CONVERGED_POSITION])
    assert not ev.convergence(TIMES, edge, TIMES, REFERENCE).converged


def test_convergence_pairs_a_sparse_reference_by_time():
    """A reference at every other time: the estimate converged at its pose paired after the last
    wrong one; the time and travel are the estimate's from its first pose."""
    est = _estimate([3.0, 3.0, 3.0, 0.1, 0.1, 3.0, 0.1, 0.1])  # pose 5 is wrong: unpaired, then paired
    c = ev.convergence(TIMES, est, TIMES[::2] + 0.004, REFERENCE[::2], odometry=REFERENCE)
    np.testing.assert_array_equal(c.est_indices, [0, 2, 4, 6])
    assert c.index == 4 and c.time == 4.0 and c.travel == pytest.approx(4.0)
    assert ev.convergence(TIMES, est, TIMES[1::2], REFERENCE[1::2]).index == 7
    with pytest.raises(ValueError, match="^times_est: no pose within max_time_difference"):
        ev.convergence(TIMES, est, TIMES + 0.5, REFERENCE)
    with pytest.raises(ValueError, match=r"^odometry: expected shape \(8, 3\)"):
        ev.convergence(TIMES, est, TIMES, REFERENCE, odometry=REFERENCE[:3])
    with pytest.raises(ValueError, match="^position_tolerance must be finite and > 0"):
        ev.convergence(TIMES, est, TIMES, REFERENCE, position_tolerance=0.0)


# --- a piece of log time, and the splice ------------------------------------------------------------

def _span_end_by_loop(t, start, seconds):
    """span_end's definition: walk the scans from ``start``, adding each step that is no clock
    jump, until ``seconds`` are reached; one past the scan that reached them."""
    k, elapsed = start, 0.0
    while k + 1 < len(t) and elapsed < seconds:
        step = t[k + 1] - t[k]
        elapsed += step if 0 < step < CLOCK_JUMP else 0.0
        k += 1
    return k + 1


def test_span_end_counts_log_time_without_clock_jumps():
    rng = np.random.default_rng(4)
    steps = rng.uniform(0.05, 0.3, 200)
    steps[[20, 90]] = [-3.0, 40.0]  # the clock going back, and jumping ahead
    t = 1000.0 + np.concatenate([[0.0], np.cumsum(steps)])
    for start in (0, 15, 85, 199, 200):
        for seconds in (0.01, 1.0, 7.5, 25.0, 1e4):
            assert span_end(t, start, seconds) == _span_end_by_loop(t, start, seconds), (start, seconds)


def _log(n=12):
    """n scans of a robot driving a quarter circle, its odometry off the truth by a drift; the
    ranges are each scan's index, to follow the rows."""
    truth = np.column_stack([5.0 * np.sin(np.linspace(0, 1.5, n)), 5.0 * (1 - np.cos(np.linspace(0, 1.5, n))),
                             np.linspace(0, 1.5, n)])
    odometry = geometry.compose([2.0, -1.0, 0.3], truth)
    robot = geometry.compose(odometry, [-0.1, 0.0, 0.0])  # the robot 10 cm behind its laser
    ranges = np.repeat(np.arange(n, dtype=float)[:, None], 3, axis=1)
    scans = io.LaserScans(ranges, odometry, robot, np.full(n, -0.1), np.full(n, 0.1), np.full(n, np.nan),
                          np.full(n, 3), 50.0 + 0.25 * np.arange(n))
    return scans, truth


def test_splice_continues_the_odometry_while_the_truth_jumps():
    scans, truth = _log()
    first, second = np.arange(1, 5), np.arange(8, 12)
    spliced = splice(scans, slice(1, 5), slice(8, 12))
    rows = np.concatenate([first, second])
    assert len(spliced) == 8
    # Every scan keeps its readings and its time.
    np.testing.assert_array_equal(spliced.ranges[:, 0], rows)
    np.testing.assert_array_equal(spliced.timestamps, scans.timestamps[rows])
    # The first piece's odometry as it was; the second's starts where the first ended ...
    np.testing.assert_array_equal(spliced.laser_poses[:4], scans.laser_poses[first])
    np.testing.assert_allclose(spliced.laser_poses[4], scans.laser_poses[4], atol=1e-12)
    # ... and moves as the log's did (each step, in the robot's frame), the robot's poses alike.
    for name in ("laser_poses", "robot_poses"):
        np.testing.assert_allclose(geometry.steps(getattr(spliced, name)[4:]),
                                   geometry.steps(getattr(scans, name)[second]), atol=1e-12)
    np.testing.assert_allclose(geometry.between(spliced.laser_poses[4:], spliced.robot_poses[4:]),
                               geometry.between(scans.laser_poses[second], scans.robot_poses[second]), atol=1e-12)
    # So the odometry sees one ordinary step across the cut, while the truth jumps.
    odometry_step = np.hypot(*np.diff(spliced.laser_poses[3:5, :2], axis=0)[0])
    truth_jump = np.hypot(*(truth[8, :2] - truth[4, :2]))
    assert odometry_step < 1e-12 and truth_jump > 2.0


def test_a_log_piece_is_a_segment_or_a_splice():
    scans, _ = _log()
    segment, jump = LogPiece(start_scan=2, segment_seconds=1.0).cut(scans)  # 4 steps of 0.25 s: scans 2-6
    assert jump is None
    np.testing.assert_array_equal(segment.ranges[:, 0], np.arange(2, 7))
    spliced, jump = LogPiece(start_scan=1, segment_seconds=0.5, splice_scan=8).cut(scans)
    assert jump == 3
    np.testing.assert_array_equal(spliced.ranges[:, 0], [1, 2, 3, 8, 9, 10])
    np.testing.assert_array_equal(spliced.laser_poses, splice(scans, slice(1, 4), slice(8, 11)).laser_poses)
    with pytest.raises(ValueError, match=r"^splice_scan: must lie in \[4, 11\]"):
        LogPiece(start_scan=1, segment_seconds=0.5, splice_scan=2).cut(scans)
    with pytest.raises(ValueError, match="^start_scan: 12 is past the log's last scan"):
        LogPiece(start_scan=12).cut(scans)
    with pytest.raises(ValueError, match="^start_scan must be >= 0"):
        LogPiece(start_scan=-1)
    with pytest.raises(TypeError, match="^splice_scan must be an integer"):
        LogPiece(splice_scan=2.5)
    with pytest.raises(ValueError, match="^segment_seconds must be finite and > 0"):
        LogPiece(segment_seconds=0)


# --- the batch localize kind's row --------------------------------------------------------------------

#: The runs here are kept small (a few hundred particles, a third of the beams), to be fast; the
#: rows are compared with the same runs made by hand, not with a figure.
SMALL = {"min_particles": 200, "max_particles": 2000, "max_beams": 20}


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """The bundled raw Intel loop, its map and a reference in the map's frame: the loop tracked in
    its map from its first odometry pose (the frame `probslam slam` made the map in). Its clock
    goes back 34 times (the raw Intel log's): the reader says so, and pairs by the nearest time."""
    log = io.read_carmen_log(data.path("intel_raw_loop.log.gz"))
    grid = io.load_ros_map(data.path("intel_raw_loop_map.yaml"))
    tracked = localize(log, grid, initial_pose=log.scans.laser_poses[0], options=default_options(log).replace(**SMALL),
                       progress=False)
    path = tmp_path_factory.mktemp("loop") / "reference.tum"
    io.write_trajectory(tracked.timestamps, tracked.poses, path)
    with pytest.warns(UserWarning, match="timestamps decrease 34 times"):
        return log, grid, str(path), io.read_trajectory(path)


def test_a_segment_row_is_the_segment_localized_and_scored_by_hand(loop):
    from probslam.batch import KINDS

    log, grid, reference, ref = loop
    values = {"start_scan": 300, "segment_seconds": 40.0, **SMALL}
    with pytest.warns(UserWarning, match="timestamps decrease"):
        row = KINDS["localize"].run(data.path("intel_raw_loop.log.gz"), values,
                                    {"map": data.path("intel_raw_loop_map.yaml"), "reference": reference,
                                     "evaluation": {"align": False}}).metrics
    scans = log.scans
    stop = span_end(scans.timestamps, 300, 40.0)
    part = scans.take(slice(300, stop))
    # Without a seed of the sweep's, the segment is seeded by its start scan.
    by_hand = localize(part, grid, options=default_options(scans).replace(seed=300, **SMALL), progress=False)
    c = ev.convergence(by_hand.timestamps, by_hand.poses, ref.timestamps, ref.poses, odometry=part.laser_poses)
    assert row["scans"] == stop - 300 == len(by_hand.timestamps)
    assert (row["converged_to_reference"], row["time_to_converge_s"], row["travel_to_converge_m"]) == (
        c.converged, c.time, c.travel)
    assert row["error_max_m"] == float(np.max(c.position_errors))
    assert row["heading_error_median_deg"] == math.degrees(float(np.median(c.heading_errors)))
    assert "jump_m" not in row and "tracked_before_jump" not in row  # a splice's (the table fills them with None)


def test_a_kidnapping_row_tracks_from_the_reference_and_scores_the_recovery(loop):
    from probslam.batch import KINDS

    log, grid, reference, ref = loop
    values = {"start_scan": 100, "segment_seconds": 30.0, "splice_scan": 450, "seed": 3, **SMALL}
    inputs = {"map": data.path("intel_raw_loop_map.yaml"), "reference": reference, "initial_pose": "reference",
              "evaluation": {"align": False}}
    with pytest.warns(UserWarning, match="timestamps decrease"):
        row = KINDS["localize"].run(data.path("intel_raw_loop.log.gz"), values, inputs).metrics
    piece = LogPiece(start_scan=100, segment_seconds=30.0, splice_scan=450)
    run = localize_log(log, grid, default_options(log).replace(seed=3, **SMALL), initial_pose=ref.poses[100],
                       piece=piece, progress=False)
    k = run.jump
    after = ev.convergence(run.result.timestamps[k:], run.result.poses[k:], ref.timestamps, ref.poses,
                           odometry=run.log.laser_poses[k:])
    assert row["jump_m"] == pytest.approx(np.hypot(*(ref.poses[450, :2] - ref.poses[100 + k - 1, :2])))
    assert row["jump_m"] > 3.0 and row["tracked_before_jump"] is True
    assert (row["converged_to_reference"], row["time_to_converge_s"], row["travel_to_converge_m"]) == (
        after.converged, after.time, after.travel)
    with pytest.raises(ValueError, match="^initial_pose: 'reference' needs a reference"):
        localize_log(log, grid, initial_pose="reference", piece=piece)


def test_a_reference_in_another_frame_is_scored_after_the_alignment_the_ate_makes(loop, tmp_path):
    """Without ``align = false`` the row's ATE aligns the estimate onto the reference, and so do
    its convergence metrics: against a reference moved rigidly, the errors are the aligned ATE's
    and the run converged from its first scan as it did against the unmoved one."""
    from probslam.batch import KINDS

    _, _, reference, ref = loop
    moved = tmp_path / "moved.tum"
    io.write_trajectory(ref.timestamps, geometry.compose([3.0, -2.0, 0.7], ref.poses), moved)
    values = {"segment_seconds": 60.0, "seed": 1, **SMALL}
    outcomes = []
    for path, evaluation in ((reference, {"align": False}), (str(moved), {})):
        inputs = {"map": data.path("intel_raw_loop_map.yaml"), "initial_pose": tuple(ref.poses[0]),
                  "reference": path, "evaluation": evaluation}
        with pytest.warns(UserWarning, match="timestamps decrease"):
            outcomes.append(KINDS["localize"].run(data.path("intel_raw_loop.log.gz"), values, inputs))
    same, aligned = (o.metrics for o in outcomes)
    assert (same["converged_to_reference"], same["time_to_converge_s"]) == (True, 0.0)
    assert (aligned["converged_to_reference"], aligned["time_to_converge_s"]) == (True, 0.0)
    with pytest.warns(UserWarning, match="timestamps decrease"):
        estimate = io.read_trajectory(outcomes[1].write_trajectory(str(tmp_path / "run")))
    ate = ev.ate(estimate.timestamps, estimate.poses, ref.timestamps, geometry.compose([3.0, -2.0, 0.7], ref.poses))
    assert aligned["error_median_m"] == pytest.approx(ate.median, abs=1e-5)  # the file's six decimals
    assert aligned["error_max_m"] == pytest.approx(ate.max, abs=1e-5)
    assert aligned["error_max_m"] < 0.2 and same["error_max_m"] < 0.2
