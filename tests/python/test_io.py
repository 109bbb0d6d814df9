"""CARMEN reader, ROS map_server files, lossless grid files, PNG pictures."""

import bz2
import gzip
import struct
import zlib

import numpy as np
import pytest

import probslam as ps
from probslam import io

LOG = """# a tiny log
PARAM robot_frontlaser_offset 0.0 nohost 0
ODOM 0 0 0 0 0 0 1.0 host 1.0
FLASER 4 1.0 2.0 3.0 4.0 0.5 0.1 0.2 0.5 0.1 0.2 2.0 host 2.0
ODOM 0.1 0 0 0.2 0.05 0 3.0 host 3.0
FLASER 4 1.5 2.5 81.83 4.5 0.6 0.1 0.25 0.6 0.1 0.25 4.0 host 4.0
"""


@pytest.mark.parametrize("suffix, opener", [(".log", open), (".log.gz", gzip.open), (".clf.bz2", bz2.open)])
def test_read_carmen_log_plain_and_compressed(tmp_path, suffix, opener):
    path = tmp_path / ("t" + suffix)
    with opener(path, "wt") as f:
        f.write(LOG)
    log = io.read_carmen_log(path)
    assert len(log.scans) == 2 and log.scans.ranges.shape == (2, 4)
    np.testing.assert_array_equal(log.scans.ranges[1], [1.5, 2.5, 81.83, 4.5])
    np.testing.assert_array_equal(log.scans.laser_poses[0], [0.5, 0.1, 0.2])
    np.testing.assert_allclose(log.scans.beam_angles()[0], np.radians([-90, -45, 0, 45]))
    np.testing.assert_array_equal(log.odometry.velocities[1], [0.2, 0.05])
    np.testing.assert_array_equal(log.scans.timestamps, [2.0, 4.0])
    assert log.params["robot_frontlaser_offset"] == "0.0"


# A real log is read even with a few bad lines: skipped, counted, listed and warned about once.
# Line 4 is garbage, line 6 has a non-numeric range, the last line was cut off mid-write.
BAD_LOG = (LOG.replace("FLASER 4 1.5 2.5", "%% garbage line %%\nODOM 0.05 0 0 0.2 0.05 0 2.5 host 2.5\nFLASER 4 1.5 oops")
           + "FLASER 4 1.5 2.5 81.83 4.5 0.6 0.1 0.25 0.6 0.1 0.25 5.0 host 5.0\n"
           + "FLASER 180 1.0 1.0 1.0")


@pytest.mark.parametrize("suffix, opener", [(".log", open), (".log.gz", gzip.open)])
def test_malformed_log_lines_are_skipped_counted_and_warned(tmp_path, suffix, opener):
    path = tmp_path / ("bad" + suffix)
    with opener(path, "wt") as f:
        f.write(BAD_LOG)
    with pytest.warns(UserWarning) as record:
        log = io.read_carmen_log(path)
    assert len(record) == 1
    message = str(record[0].message)
    assert message.startswith(f"{path}: skipped 3 malformed lines (lines 6, 8, 10;")
    assert "'%%' is not a CARMEN message name" in message
    np.testing.assert_array_equal(log.scans.timestamps, [2.0, 5.0])
    np.testing.assert_array_equal(log.scans.ranges[1], [1.5, 2.5, 81.83, 4.5])
    assert len(log.odometry.poses) == 3
    assert log.skipped_rows == 3 and log.skipped_lines == [6, 8, 10]
    assert "('oops') is not a number" in log.skipped_reasons[1]
    assert "FLASER has 5 fields, expected at least 188" in log.skipped_reasons[2]


def test_many_bad_lines_are_counted_and_the_first_listed(tmp_path):
    path = tmp_path / "many.log"
    path.write_text(LOG + "ODOM 1 2\n" * 30)
    with pytest.warns(UserWarning, match=r"skipped 30 malformed lines \(lines 7, 8, .*, 26, \.\.\.; first: ODOM has 3"):
        log = io.read_carmen_log(path)
    assert log.skipped_rows == 30 and log.skipped_lines == list(range(7, 7 + io.carmen.MAX_REPORTED_LINES))
    assert len(log.scans) == 2


def test_clean_log_does_not_warn(tmp_path, recwarn):
    path = tmp_path / "t.log"
    path.write_text(LOG + "NEFF 12\n")  # a message type the reader does not use is not a bad line
    log = io.read_carmen_log(path)
    assert log.skipped_rows == 0 and log.skipped_lines == [] and len(recwarn) == 0


def test_log_without_a_valid_scan_is_an_error(tmp_path):
    garbage = tmp_path / "garbage.log.gz"
    with gzip.open(garbage, "wt") as f:
        f.write("\nthis is not\na CARMEN log\n%%%\n")
    with pytest.raises(ValueError, match=r"garbage\.log\.gz: no laser scan .*3 malformed lines skipped, the first "
                                         r".*garbage\.log\.gz:2: 'this' is not a CARMEN message name"):
        io.read_carmen_log(garbage)
    truncated = tmp_path / "short.log"
    truncated.write_text("ODOM 1 2\n")
    with pytest.raises(ValueError, match=r"short\.log: no laser scan.*1 malformed line skipped.*short\.log:1:"):
        io.read_carmen_log(truncated)
    only_bad_scans = tmp_path / "bad.log"
    only_bad_scans.write_text(LOG.replace("FLASER 4 1.0 2.0", "FLASER 4 1.0 x").replace("FLASER 4 1.5", "FLASER 9 1.5"))
    with pytest.raises(ValueError, match=r"bad\.log: .*2 malformed lines skipped.*bad\.log:4: field 4 \('x'\)"):
        io.read_carmen_log(only_bad_scans)
    with pytest.raises(FileNotFoundError, match="path"):
        io.read_carmen_log(tmp_path / "missing.log")


def test_ros_map_round_trip_and_file_format(tmp_path):
    grid = ps.OccupancyGrid2D(0.05, 6, 4, origin=(-1.0, 2.0))
    grid.log_odds[0, 0] = 3.0    # occupied, bottom-left
    grid.log_odds[3, 5] = -3.0   # free, top-right
    grid.log_odds[1, 1] = 0.3    # p = 0.57: unknown
    io.save_ros_map(grid, tmp_path / "m.yaml")
    meta = dict(line.split(": ", 1) for line in (tmp_path / "m.yaml").read_text().splitlines())
    assert meta["image"] == "m.pgm" and meta["mode"] == "trinary" and meta["negate"] == "0"
    assert [float(v) for v in meta["origin"].strip("[]").split(",")] == [-1.0, 2.0, 0.0]
    raw = (tmp_path / "m.pgm").read_bytes()
    assert raw.startswith(b"P5\n")
    pixels = np.frombuffer(raw[-24:], np.uint8).reshape(4, 6)  # row 0 = top of the map
    assert pixels[3, 0] == 0 and pixels[0, 5] == 254 and pixels[2, 1] == 205
    back = io.load_ros_map(tmp_path / "m.yaml")
    assert back.same_geometry(grid)
    cls = lambda g: np.digitize(g.probability(), [0.196, 0.65])
    np.testing.assert_array_equal(cls(back), cls(grid))


def test_ros_map_malformed(tmp_path):
    yaml = tmp_path / "bad.yaml"
    yaml.write_text("image: none.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    with pytest.raises(ValueError, match="none.pgm"):
        io.load_ros_map(yaml)
    yaml.write_text("image: none.pgm\nresolution: 0.1\norigin: [0, 0, 0.5]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    with pytest.raises(ValueError, match=r"bad\.yaml:3.*yaw"):
        io.load_ros_map(yaml)
    (tmp_path / "t.pgm").write_bytes(b"P5\n100 100\n255\n" + bytes(10))
    yaml.write_text("image: t.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    with pytest.raises(ValueError, match="truncated"):
        io.load_ros_map(yaml)


def test_lossless_grid_file_is_the_state_file(tmp_path):
    # One lossless grid format (issue 36): OccupancyGrid2D.save / load; every parameter comes back.
    grid = ps.OccupancyGrid2D(0.07, 9, 5, origin=(0.3, -0.2), p_prior=0.4, clamp=None, p_hit=0.8, p_miss=0.3)
    grid.log_odds[:] = np.random.default_rng(0).normal(size=(5, 9))
    grid.save(tmp_path / "g.psl")
    back = ps.OccupancyGrid2D.load(tmp_path / "g.psl")
    np.testing.assert_array_equal(back.log_odds, grid.log_odds)
    assert (back.p_prior, back.clamp, back.p_hit, back.p_miss) == (0.4, None, 0.8, 0.3)
    assert back.same_geometry(grid)
    data = (tmp_path / "g.psl").read_bytes()
    (tmp_path / "cut.psl").write_bytes(data[:-3])
    with pytest.raises(ValueError, match="cut.psl"):
        ps.OccupancyGrid2D.load(tmp_path / "cut.psl")
    assert not hasattr(io, "save_grid") and not hasattr(io, "load_grid")


def test_png_is_a_valid_image(tmp_path):
    grid = ps.OccupancyGrid2D(0.1, 7, 3)
    grid.log_odds[0, :] = 5.0
    io.write_png(grid, tmp_path / "m.png", trajectory=np.array([[0.05, 0.25, 0.0]]))
    data = (tmp_path / "m.png").read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    w, h, depth, colour = struct.unpack(">IIBB", data[16:26])
    assert (w, h, depth, colour) == (7, 3, 8, 2)
    idat = data[data.index(b"IDAT") + 4:data.index(b"IEND") - 8]
    rows = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(3, 1 + 7 * 3)
    dark = round(255 * (1 - ps.probability_from_log_odds(5.0)))
    assert rows[2, 1 + 3 * 1] == dark == 2  # bottom row (grid row 0) is occupied: nearly black
    assert tuple(rows[0, 1:4]) == (220, 30, 30)  # the trajectory point in row 2, column 0


def test_real_corrected_logs(shared_data):
    intel = io.read_carmen_log(shared_data / "laser_2d/intel/intel-corrected.log.gz")
    assert intel.scans.ranges.shape == (910, 180) and len(intel.odometry.poses) == 14541
    assert intel.skipped_rows == 0
    np.testing.assert_allclose(intel.scans.angular_resolutions, np.pi / 180)
    fr079 = io.read_carmen_log(shared_data / "laser_2d/fr079/freiburg-079-corrected.log.gz")
    assert fr079.scans.ranges.shape == (4791, 360)
    np.testing.assert_allclose(fr079.scans.beam_angles()[0, [0, -1]], np.radians([-90, 89.5]))
    csail = io.read_carmen_log(shared_data / "laser_2d/mit_csail/csail-corrected.log.gz")
    np.testing.assert_allclose(csail.scans.beam_angles()[0, [0, -1]], np.radians([-90, 90]))
