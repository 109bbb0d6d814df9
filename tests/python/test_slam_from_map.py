"""``probslam slam --map`` / ``run_slam(initial_map=...)``: a run that starts from a saved map
(issue 36). The log is cut in two halves; the first half's map, saved by ``slam``, is where the
second half starts, and the second half must land where the uninterrupted run put it."""

import gzip

import numpy as np
import pytest

import probslam as ps
from probslam import cli, io
from probslam.slam import default_options, run_slam
from probslam.data import path as data_path

# Each test runs SLAM over the bundled Intel lap (slow: seconds here, minutes under the sanitizers,
# which the reliability files cover for the same C++ classes).
pytestmark = pytest.mark.slow

#: Where the second half starts, run on the first half's saved map, against the uninterrupted
#: run (m): its first scans must be where the uninterrupted run put them, to about a cell (5 cm;
#: measured 0.006 to 0.02 m over the first 20 scans).
SAME_START_M = 0.05
#: The whole second half against the uninterrupted run (m). Not near zero: the bundled loop
#: closes no loop (the uninterrupted run finds none either), so both second halves are scan
#: matching alone, against different maps (the uninterrupted run's open submap, the other's
#: saved first-half map quantised to map_server's trinary PGM), and their drift differs: measured
#: at the worst scan 0.21 m with the correlative search for every scan, 0.35 m with the frontend's
#: local optimiser (issue 54; from the first half's grid instead of its PGM 0.28 m both ways, the
#: median 0.18 m searched, 0.14 m local). 0.45 m keeps a margin; a wrong frame or start pose
#: gives metres.
SAME_PLACE_M = 0.45
#: Headings agree to this (rad): the same drift, measured 0.02 rad at most.
SAME_HEADING_RAD = 0.05
#: run_slam on a map it made itself, from its own first pose: the first scan is matched against
#: the whole log's map (walls drawn from every pose, so a little thicker), measured 0.058 m off
#: (just over a cell) for the standing start; two cells allowed.
OWN_START_M = 0.1
#: ... and the rest matched against more than the first run had (the whole map from the start):
#: measured 0.28 m at most.
OWN_MAP_M = 0.35


def split_log(tmp_path):
    """The bundled raw loop as two CARMEN logs (PARAM lines in both) and the index of the first
    scan of the second half."""
    lines = gzip.decompress(open(data_path(cli.BUNDLED_RAW_LOG), "rb").read()).decode().splitlines(True)
    params = [s for s in lines if not s.startswith("FLASER")]
    lasers = [s for s in lines if s.startswith("FLASER")]
    half = len(lasers) // 2
    (tmp_path / "first.log").write_text("".join(params + lasers[:half]))
    (tmp_path / "second.log").write_text("".join(params + lasers[half:]))
    return half


def start_pose(first_poses, odometry, half):
    """Where the second half starts in the first half's frame: the first half's last pose moved by
    the odometry from its scan to the next (what a user knows, not the uninterrupted run's answer)."""
    last = ps.Pose2(*first_poses[-1])
    step = ps.Pose2(*odometry[half - 1]).between(ps.Pose2(*odometry[half]))
    p = last.compose(step)
    return [p.x, p.y, p.theta]


def angle_diff(a, b):
    return np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.filterwarnings("ignore:.*timestamps decrease")  # the raw Intel log's clock steps back
def test_second_half_on_the_first_halfs_saved_map(tmp_path, capsys):
    half = split_log(tmp_path)
    full = data_path(cli.BUNDLED_RAW_LOG)
    opts = ["--no-progress", "--no-plot"]
    assert cli.main(["slam", full, "-o", str(tmp_path / "whole")] + opts) == 0
    assert cli.main(["slam", str(tmp_path / "first.log"), "-o", str(tmp_path / "first")] + opts) == 0
    first = io.read_trajectory(tmp_path / "first_trajectory.tum")
    odometry = io.read_carmen_log(full).scans.laser_poses
    pose = start_pose(first.poses, odometry, half)
    assert cli.main(["slam", str(tmp_path / "second.log"), "--map", str(tmp_path / "first.yaml"),
                     "--initial-pose", *map(str, pose), "-o", str(tmp_path / "second")] + opts) == 0
    out = capsys.readouterr().out
    assert "started from:" in out
    whole = io.read_trajectory(tmp_path / "whole_trajectory.tum")
    second = io.read_trajectory(tmp_path / "second_trajectory.tum")
    np.testing.assert_array_equal(second.timestamps, whole.timestamps[half:])
    gap = np.hypot(*(second.poses[:, :2] - whole.poses[half:, :2]).T)
    assert gap[:20].max() < SAME_START_M, f"first scans off by {gap[:20].max():.3f} m"
    assert gap.max() < SAME_PLACE_M, f"largest gap {gap.max():.3f} m at scan {half + gap.argmax()}"
    assert angle_diff(second.poses[:, 2], whole.poses[half:, 2]).max() < SAME_HEADING_RAD
    # The written map is the saved one with the second half drawn in: it holds the first map's
    # extent, on its lattice.
    saved, written = io.load_ros_map(tmp_path / "first.yaml"), io.load_ros_map(tmp_path / "second.yaml")
    lo, hi = np.asarray(saved.origin), np.asarray(saved.origin) + saved.resolution * np.array([saved.width, saved.height])
    wlo = np.asarray(written.origin)
    whi = wlo + written.resolution * np.array([written.width, written.height])
    assert np.all(wlo <= lo + 1e-9) and np.all(whi >= hi - 1e-9)
    shift = (wlo - lo) / saved.resolution
    np.testing.assert_allclose(shift, np.round(shift), atol=1e-6)


def test_run_slam_on_a_map_grid_or_state_file(tmp_path):
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    first = run_slam(log, progress=False)
    first.grid.save(tmp_path / "grid.psl")
    # The whole log again, on its own map, from its own first pose: it stays where it was.
    again = run_slam(log, progress=False, initial_map=tmp_path / "grid.psl", initial_pose=first.poses[0])
    gap = np.hypot(*(again.poses[:, :2] - first.poses[:, :2]).T)
    assert gap[:20].max() < OWN_START_M and gap.max() < OWN_MAP_M
    from_object = run_slam(log, progress=False, initial_map=first.grid, initial_pose=first.poses[0])
    np.testing.assert_array_equal(from_object.poses, again.poses)
    assert again.submap_poses[0].tolist() == [0.0, 0.0, 0.0]  # the map's node, fixed at its origin
    # A run on a map saves and resumes as any other (the run file holds the map).
    n = 300
    head = io.LaserScans(**{k: getattr(log, k)[:n] for k in log.__dataclass_fields__})
    run_slam(head, progress=False, initial_map=first.grid, initial_pose=first.poses[0], save=tmp_path / "run.psl")
    resumed = run_slam(log, progress=False, resume=tmp_path / "run.psl")
    np.testing.assert_array_equal(resumed.poses, from_object.poses)
    np.testing.assert_array_equal(resumed.grid.log_odds, from_object.grid.log_odds)


def test_bad_maps_and_poses_are_refused_by_name(tmp_path):
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    room = run_slam(log, progress=False).grid
    with pytest.raises(FileNotFoundError, match="initial_map"):
        run_slam(log, progress=False, initial_map=tmp_path / "missing.psl")
    with pytest.raises(FileNotFoundError, match="missing.yaml"):
        run_slam(log, progress=False, initial_map=tmp_path / "missing.yaml")
    (tmp_path / "junk.psl").write_bytes(b"junk")
    with pytest.raises(ValueError, match="initial_map: .*not a probslam state file"):
        run_slam(log, progress=False, initial_map=tmp_path / "junk.psl")
    with pytest.raises(TypeError, match="initial_map"):
        run_slam(log, progress=False, initial_map=3)
    empty = ps.OccupancyGrid2D(0.05, 100, 100, origin=(-2.5, -2.5))
    with pytest.raises(ValueError, match="map has no occupied cell"):
        run_slam(log, progress=False, initial_map=empty)
    with pytest.raises(ValueError, match="initial_pose .*outside the map"):
        run_slam(log, progress=False, initial_map=room, initial_pose=(1e3, 0.0, 0.0))
    with pytest.raises(ValueError, match="initial_pose"):
        run_slam(log, progress=False, initial_map=room, initial_pose=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="map has resolution"):
        run_slam(log, progress=False, initial_map=room,
                 options=default_options(log).replace(frontend={"resolution": 0.1}))
    with pytest.raises(ValueError, match="initial_pose: only with initial_map"):
        run_slam(log, progress=False, initial_pose=(0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="initial_pose .*outside the map"):
        run_slam(log, progress=False, method="rbpf", initial_map=room, initial_pose=(1e3, 0.0, 0.0))
    # The CLI: one line on stderr, exit 2.
    opts = ["--no-progress", "--no-plot", "-o", str(tmp_path / "x")]
    assert cli.main(["slam", "--map", str(tmp_path / "missing.yaml")] + opts) == 2
    io.save_ros_map(empty, tmp_path / "empty.yaml")
    assert cli.main(["slam", "--map", str(tmp_path / "empty.yaml")] + opts) == 2
    io.save_ros_map(room, tmp_path / "room.yaml")
    assert cli.main(["slam", "--map", str(tmp_path / "room.yaml"), "--initial-pose", "1000", "0", "0"] + opts) == 2
    assert cli.main(["slam", "--initial-pose", "0", "0", "0"] + opts) == 2
    # The object refuses a second start, and a start after scans.
    slam = ps.SubmapSlam2D()
    slam.start_from_map(room)
    with pytest.raises(ValueError, match="map"):
        slam.start_from_map(room)
    with pytest.raises(TypeError, match="map: expected an OccupancyGrid2D"):
        ps.SubmapSlam2D().start_from_map("room.yaml")
    rbpf = ps.GridFastSlam(num_particles=2)
    rbpf.start_from_map(room)
    with pytest.raises(ValueError, match="map"):
        rbpf.start_from_map(room)
    assert rbpf.start_map.same_geometry(room)


def test_rbpf_starts_on_a_saved_map():
    # Grid FastSLAM on the graph run's map, from the graph run's first pose: in the map's frame,
    # near the graph run (measured 0.058 m over the first scans, 0.17 m at most: the two methods'
    # own differences, 0.20 m without the map).
    log = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    graph = run_slam(log, progress=False)
    options = default_options(log, "rbpf", initial_map=graph.grid).replace(num_particles=3)
    assert options.resolution == graph.grid.resolution
    rbpf = run_slam(log, progress=False, options=options, initial_map=graph.grid, initial_pose=graph.poses[0])
    gap = np.hypot(*(rbpf.poses[:, :2] - graph.poses[:, :2]).T)
    assert gap[:20].max() < OWN_START_M and gap.max() < OWN_MAP_M
    assert rbpf.tile_sharing.distinct < rbpf.tile_sharing.references  # the particles share the map's tiles
    # The written map holds the saved one, on its lattice.
    shift = (np.asarray(rbpf.grid.origin) - np.asarray(graph.grid.origin)) / graph.grid.resolution
    np.testing.assert_allclose(shift, np.round(shift), atol=1e-6)
