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


def test_malformed_log_line_reports_line_number(tmp_path):
    path = tmp_path / "bad.log.gz"
    with gzip.open(path, "wt") as f:
        f.write(LOG.replace("FLASER 4 1.5 2.5", "FLASER 4 1.5 oops"))
    with pytest.raises(ValueError, match=r"bad\.log\.gz:6:.*oops"):
        io.read_carmen_log(path)
    truncated = tmp_path / "short.log"
    truncated.write_text("ODOM 1 2\n")
    with pytest.raises(ValueError, match=r"short\.log:1:"):
        io.read_carmen_log(truncated)
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


def test_lossless_grid_round_trip_and_corrupt_files(tmp_path):
    grid = ps.OccupancyGrid2D(0.07, 9, 5, origin=(0.3, -0.2), p_prior=0.4, clamp=None, p_hit=0.8, p_miss=0.3)
    grid.log_odds[:] = np.random.default_rng(0).normal(size=(5, 9))
    io.save_grid(grid, tmp_path / "g.grid")
    back = io.load_grid(tmp_path / "g.grid")
    np.testing.assert_array_equal(back.log_odds, grid.log_odds)
    assert (back.p_prior, back.clamp, back.p_hit, back.p_miss) == (0.4, None, 0.8, 0.3)
    data = (tmp_path / "g.grid").read_bytes()
    (tmp_path / "cut.grid").write_bytes(data[:-3])
    with pytest.raises(ValueError, match="cut.grid"):
        io.load_grid(tmp_path / "cut.grid")
    (tmp_path / "huge.grid").write_bytes(data[:12] + struct.pack("<ii", 2**30, 2**30) + data[20:])
    with pytest.raises(ValueError, match="huge.grid"):
        io.load_grid(tmp_path / "huge.grid")


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
    np.testing.assert_allclose(intel.scans.angular_resolutions, np.pi / 180)
    fr079 = io.read_carmen_log(shared_data / "laser_2d/fr079/freiburg-079-corrected.log.gz")
    assert fr079.scans.ranges.shape == (4791, 360)
    np.testing.assert_allclose(fr079.scans.beam_angles()[0, [0, -1]], np.radians([-90, 89.5]))
    csail = io.read_carmen_log(shared_data / "laser_2d/mit_csail/csail-corrected.log.gz")
    np.testing.assert_allclose(csail.scans.beam_angles()[0, [0, -1]], np.radians([-90, 90]))
