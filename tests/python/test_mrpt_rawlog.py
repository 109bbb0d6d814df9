"""probslam.io.mrpt_rawlog (laser scans -> MRPT rawlog for bench_slam_cost.py's MRPT rows): the
rawlog read back by a parser written here from MRPT's serialization layout, against the CARMEN
log as probslam reads it; and by MRPT's own rawlog-edit when mrpt-apps is installed."""

import dataclasses
import math
import pathlib
import re
import shutil
import struct
import subprocess

import numpy as np
import pytest

from probslam import cli, io
from probslam.io import mrpt_rawlog
from probslam.data import path as data_path

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCANS = 60
#: Ranges and angles go through float32 in the rawlog (MRPT stores ranges and aperture so).
FLOAT32_RANGE_TOL = 1e-5  # m, for readings below 82 m
FLOAT32_ANGLE_TOL = 1e-6  # rad: float32 aperture (~3.1 rad) times a beam fraction
#: Odometry increments are doubles: chaining them back reproduces the poses up to rounding.
CHAIN_TOL = 1e-9


@pytest.fixture(scope="module")
def scans():
    s = io.read_carmen_log(data_path(cli.BUNDLED_RAW_LOG)).scans
    return dataclasses.replace(s, **{f.name: getattr(s, f.name)[:SCANS] for f in dataclasses.fields(s)})


class Reader:
    """MRPT CArchive objects: (name length | 0x80) name, version, fields, 0x88."""

    def __init__(self, data):
        self.data, self.pos = data, 0

    def take(self, fmt):
        values = struct.unpack_from("<" + fmt, self.data, self.pos)
        self.pos += struct.calcsize("<" + fmt)
        return values if len(values) > 1 else values[0]

    def begin(self, expected):
        n = self.take("B")
        assert n & 0x80, f"object header at {self.pos - 1}"
        name = self.data[self.pos:self.pos + (n & 0x7F)].decode()
        self.pos += n & 0x7F
        assert name == expected, (name, expected)
        return self.take("B")

    def end(self):
        assert self.take("B") == 0x88, f"end flag at {self.pos - 1}"

    def pose2d(self):
        assert self.begin("mrpt::poses::CPose2D") == 1
        xyz = self.take("3d")
        self.end()
        return xyz

    def action(self):
        assert self.begin("mrpt::obs::CActionCollection") == 0
        assert self.take("I") == 1
        assert self.begin("mrpt::obs::CActionRobotMovement2D") == 7
        assert self.take("I") == 0  # estimated from odometry
        increment = self.pose2d()
        self.take("I6fI6f")  # motion model selection and parameters
        has_velocities, has_encoders, ticks = self.take("??Q")
        assert not has_velocities and not has_encoders
        self.end()
        self.end()
        return increment, ticks

    def frame(self):
        assert self.begin("mrpt::obs::CSensoryFrame") == 2
        assert self.take("I") == 1
        assert self.begin("mrpt::obs::CObservation2DRangeScan") == 7
        aperture, right_to_left, max_range = self.take("f?f")
        assert self.begin("mrpt::poses::CPose3D") == 3
        pose = self.take("12d")
        self.end()
        n = self.take("I")
        ranges = np.frombuffer(self.data, "<f4", n, self.pos)
        valid = np.frombuffer(self.data, np.uint8, n, self.pos + 4 * n).astype(bool)
        self.pos += 5 * n
        _std, ticks, _beam_aperture = self.take("fQf")
        label_length = self.take("I")
        label = self.data[self.pos:self.pos + label_length].decode()
        self.pos += label_length
        _delta_pitch, has_intensity = self.take("d?")
        assert not has_intensity and label == "FLASER"
        self.end()
        self.end()
        return dict(aperture=aperture, right_to_left=right_to_left, max_range=max_range, pose=pose,
                    ranges=ranges, valid=valid, ticks=ticks)


def read_pairs(data):
    reader, pairs = Reader(data), []
    while reader.pos < len(data):
        pairs.append((reader.action(), reader.frame()))
    return pairs


def seconds(ticks):
    return (ticks - 116_444_736_000_000_000) / 1e7


def test_rawlog_holds_the_scans_odometry_and_timestamps(scans, tmp_path):
    path = tmp_path / "intel.rawlog"
    with open(path, "wb") as f:
        assert mrpt_rawlog.write_rawlog(scans, f) == SCANS
    pairs = read_pairs(path.read_bytes())
    assert len(pairs) == SCANS
    no_return = scans.no_return_range()
    pose = scans.robot_poses[0].copy()
    for i, ((increment, action_ticks), scan) in enumerate(pairs):
        t = float(scans.timestamps[i])
        # 100 ns ticks: the FLASER timestamp to within a tick
        assert abs(seconds(action_ticks) - t) < 2e-7 and abs(seconds(scan["ticks"]) - t) < 2e-7
        # Chaining the increments gives back the odometry poses.
        c, s = math.cos(pose[2]), math.sin(pose[2])
        pose = np.array([pose[0] + c * increment[0] - s * increment[1], pose[1] + s * increment[0] + c * increment[1],
                         pose[2] + increment[2]])
        assert np.allclose(pose[:2], scans.robot_poses[i, :2], atol=CHAIN_TOL, rtol=0)
        assert abs(math.remainder(pose[2] - scans.robot_poses[i, 2], 2 * math.pi)) < CHAIN_TOL
        n = int(scans.num_beams[i])
        z = scans.ranges[i, :n]
        assert len(scan["ranges"]) == n and scan["right_to_left"]
        expect_valid = np.isfinite(z) & (z > 0) & (z < no_return)
        assert np.array_equal(scan["valid"], expect_valid)
        assert np.allclose(scan["ranges"][expect_valid], z[expect_valid], atol=FLOAT32_RANGE_TOL, rtol=0)
        # MRPT's bearing of beam k: sensor yaw - aperture / 2 + k * aperture / (n - 1); the
        # rotation is row major, yaw = atan2(R10, R00).
        yaw = math.atan2(scan["pose"][3 + 3], scan["pose"][3])
        k = np.arange(n)
        mrpt = yaw - scan["aperture"] / 2 + k * scan["aperture"] / (n - 1)
        carmen = scans.start_angles[i] + k * scans.angular_resolutions[i]
        assert np.allclose(mrpt, carmen, atol=FLOAT32_ANGLE_TOL, rtol=0)
    assert pairs[0][0][0] == (0.0, 0.0, 0.0)


def test_an_empty_log_is_refused(scans, tmp_path):
    empty = dataclasses.replace(scans, **{f.name: getattr(scans, f.name)[:0] for f in dataclasses.fields(scans)})
    with open(tmp_path / "empty.rawlog", "wb") as f, pytest.raises(ValueError, match="scans"):
        mrpt_rawlog.write_rawlog(empty, f)


@pytest.mark.skipif(shutil.which("rawlog-edit") is None, reason="MRPT's rawlog-edit (mrpt-apps) is not installed")
def test_mrpt_reads_the_rawlog(scans, tmp_path):
    path = tmp_path / "intel.rawlog"
    with open(path, "wb") as f:
        mrpt_rawlog.write_rawlog(scans, f)
    done = subprocess.run(["rawlog-edit", "--info", "-i", str(path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    info = dict(re.findall(r"^(.+?)\s+:\s+(.*)$", done.stdout, flags=re.M))
    assert info["Actions/SensoryFrame format"] == "Yes"
    assert int(info["Overall number of objects"]) == 2 * SCANS
    assert float(info["Earliest timestamp"].split()[0]) == pytest.approx(scans.timestamps[0], abs=1e-6)
    assert float(info["Latest timestamp"].split()[0]) == pytest.approx(scans.timestamps[-1], abs=1e-6)
