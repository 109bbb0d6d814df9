"""What the laser SLAM classes report of their cost (issue 40): per-stage processor time and the
bytes SubmapSlam2D holds, and the memory cuts that must not change a result: finished submaps'
grids are released (the loop-closure search keeps their obstacle cells), and the search's field
cache only trades time for memory."""

import dataclasses
import pickle

import numpy as np

import pytest

from probslam import _core, cli, io
from probslam.slam import default_options, run_slam
from probslam.data import path as data_path

# Each test runs SLAM over a whole log (slow: minutes under the sanitizers, which the reliability
# files cover for the same C++ classes).
pytestmark = pytest.mark.slow

#: Scans of the bundled raw Intel loop: enough for a dozen 3 m submaps and closure searches.
SCANS = 400
GRID_CELL_BYTES = 12  # log-odds (double) and scan stamp (uint32) per cell


@pytest.fixture(scope="module")
def log():
    scans = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    return dataclasses.replace(scans, **{f.name: getattr(scans, f.name)[:SCANS] for f in dataclasses.fields(scans)})


def slam_on(log, **closures):
    slam = _core.SubmapSlam2D(frontend={"submap_distance": 3.0}, closures=closures)
    slam.add_scans(log.ranges, log.beam_angles(), log.laser_poses, log.timestamps)
    slam.finish()
    return slam


def test_results_do_not_depend_on_the_field_cache(log):
    # A cache too small for one field rebuilds every field it is asked for; a large one builds
    # each once: the closures, the graph and the map must be the same bit for bit.
    small, large = slam_on(log, field_cache_bytes=1024.0), slam_on(log, field_cache_bytes=2.0 ** 30)
    assert small.summary.closures_searched > 0 and small.num_submaps >= 6, small.summary
    assert np.array_equal(small.scan_poses, large.scan_poses)
    a, b = small.constraints, large.constraints
    assert np.array_equal(a.measurement, b.measurement) and np.array_equal(a.active, b.active)
    assert np.array_equal(small.map().log_odds, large.map().log_odds)
    ts, tl = small.timings.as_dict(), large.timings.as_dict()
    assert ts["closure_matches"] == tl["closure_matches"] == small.summary.closures_searched
    assert ts["closure_fields_built"] >= tl["closure_fields_built"] > 0
    assert small.memory.closure_fields <= large.memory.closure_fields


def test_finished_submap_grids_are_released(log):
    slam = slam_on(log)
    # The frontend alone (same options) keeps every submap's grid: the reference.
    ism = _core.IncrementalScanMatcher(submap_distance=3.0)
    ism.add_scans(log.ranges, log.beam_angles(), log.laser_poses, log.timestamps)
    assert ism.num_submaps == slam.num_submaps
    grids = [ism.submap_grid(k) for k in range(ism.num_submaps)]
    held = sum(g.width * g.height for g in grids) * GRID_CELL_BYTES
    last = grids[-1].width * grids[-1].height * GRID_CELL_BYTES
    m = dict(slam.memory.as_dict(), total=slam.memory.total)
    # The open submap's grid, and one cell for each finished one.
    assert m["submap_grids"] == last + (len(grids) - 1) * GRID_CELL_BYTES
    assert 0 < m["closure_cells"] < held / 12
    assert m["total"] == pytest.approx(sum(v for k, v in m.items() if k != "total"))
    assert m["scans"] >= 16 * SCANS  # at least the ranges and angles


def test_saved_state_continues_after_release(tmp_path, log):
    # The file holds the released submaps as their obstacle cells: a loaded object searches the
    # same fields, so it continues exactly as the original.
    half = SCANS // 2
    a = _core.SubmapSlam2D(frontend={"submap_distance": 3.0})
    angles = log.beam_angles()
    a.add_scans(log.ranges[:half], angles[:half], log.laser_poses[:half], log.timestamps[:half])
    a.save(tmp_path / "s.psl")
    b = _core.SubmapSlam2D.load(tmp_path / "s.psl")
    assert b.memory.closure_cells == a.memory.closure_cells
    for s in (a, b):
        s.add_scans(log.ranges[half:], angles[half:], log.laser_poses[half:], log.timestamps[half:])
        s.finish()
    assert np.array_equal(a.scan_poses, b.scan_poses)
    assert np.array_equal(a.constraints.measurement, b.constraints.measurement)


def test_timings_count_every_stage(log):
    slam = slam_on(log)
    before = slam.timings.final_map
    slam.map()
    t = slam.timings.as_dict()
    assert set(t) == {"filter", "match", "insert", "closure_search", "closure_fields", "optimize", "final_map",
                      "frontend_fields", "closure_fields_built", "closure_matches", "frontend_local",
                      "frontend_searches"}
    assert all(v >= 0 for v in t.values())
    assert t["match"] > 0 and t["insert"] > 0 and t["final_map"] > before
    assert t["closure_fields"] <= t["closure_search"] and t["frontend_fields"] > 0
    # Every scan the frontend matched (the first is placed, not matched) went one way or the
    # other (issue 54; a match that failed its quality test counts too); a log with odometry is
    # matched mostly by the local optimiser.
    assert t["frontend_local"] + t["frontend_searches"] >= slam.summary.matched_scans - 1
    assert t["frontend_local"] > t["frontend_searches"]
    # A copy carries the counts.
    assert slam.copy().timings.as_dict() == t
    # A bound report: read-only fields, equal after pickling, the fields in its repr.
    timings = slam.timings
    with pytest.raises(AttributeError):
        timings.match = 0.0
    assert pickle.loads(pickle.dumps(timings)) == timings
    assert repr(timings).startswith(f"SubmapSlamTimings(filter={timings.filter!r}, match={timings.match!r}")


def test_run_slam_reports_timings_and_memory(log):
    r = run_slam(log, progress=False)
    assert r.timings.match > 0 and r.memory.total > 0
    f = run_slam(log, progress=False, options=default_options(log, "rbpf").replace(num_particles=3))
    assert f.memory is None
    t = f.timings.as_dict()
    assert set(t) == {"filter", "corrector", "proposal", "resample", "map_update", "table_copies", "final_map",
                      "proposals", "proposal_local", "proposal_evaluations", "corrector_local", "corrector_searches"}
    assert all(v >= 0 for v in t.values())
    assert t["proposal"] > 0 and t["map_update"] > 0 and t["final_map"] > 0 and t["table_copies"] <= t["map_update"]
    # Counts: every proposal evaluates the likelihood (at least the 27 poses of its fit when it
    # matched); the corrector matched scans by the search, the local optimiser, or both ways.
    assert 0 <= t["proposal_local"] <= t["proposals"] > 0 and t["proposal_evaluations"] >= t["proposals"]
    assert t["corrector_local"] + t["corrector_searches"] > 0
