"""The original Victoria Park run (ACFR; issue 50): its reader against a hand parse of small
files, the row policy (bad rows skipped and counted, too many refused), the fast parse against
the row loop it stands for, and the real run's figures from its README."""

from __future__ import annotations

import bz2
import gzip
import math

import numpy as np
import pytest

import probslam as ps
from probslam.datasets import landmark_dataset_kind, load_landmark_dataset, victoria_park_acfr
from probslam.io import VictoriaParkAcfr, read_victoria_park_acfr
from probslam.io._files import numeric_rows, numeric_table
from probslam.io.landmark_datasets import MAX_BAD_ROW_FRACTION

INPUTS = """\
     0.973      0.000    -0.0035
     0.998      0.512    -0.0042
     1.023      1.250     0.3100
     1.048      1.300    -0.2500
"""
# Unsorted on purpose: the scan at 1.000 comes after the one at 1.200 in the file, and rows of
# one scan must keep the file's order.
MEASUREMENTS = """\
     0.852   20.46202    0.88575    0.35404
     0.852   29.59859    1.02102    0.25717
     1.200    5.00000    3.14159    0.10000
     1.000    7.50000    0.00000    0.20000
     1.000    8.25000    1.57080    0.30000
     1.000    9.00000    2.50000    0.40000
"""
GPS = """\
     0.000     -67.6493     -41.7142
     1.001     -67.7310     -41.6681
"""


def write_run(folder, inputs=INPUTS, measurements=MEASUREMENTS, gps=GPS):
    folder.mkdir(exist_ok=True)
    (folder / "inputs.dat").write_text(inputs)
    (folder / "measurements.dat").write_text(measurements)
    if gps is not None:
        (folder / "gps.dat").write_text(gps)
    return folder


def hand_parse(text):
    rows = [[float(x) for x in line.split()] for line in text.splitlines() if line.strip()]
    return sorted(rows, key=lambda row: row[0])  # Python's sort is stable


def test_reader_against_a_hand_parse(tmp_path):
    data = read_victoria_park_acfr(write_run(tmp_path / "run"))
    assert isinstance(data, VictoriaParkAcfr) and data.skipped_rows == {}
    np.testing.assert_array_equal(data.inputs, hand_parse(INPUTS))
    np.testing.assert_array_equal(data.gps, hand_parse(GPS))
    expected = hand_parse(MEASUREMENTS)
    for row in expected:  # the detector's angle from the vehicle's right -> the vehicle frame
        row[2] = math.remainder(row[2] - math.pi / 2, 2 * math.pi)
    np.testing.assert_allclose(data.measurements, expected, rtol=0, atol=1e-15)
    assert np.all((-math.pi < data.measurements[:, 2]) & (data.measurements[:, 2] <= math.pi))
    # 0 at the right -> -pi/2; pi/2 ahead -> 0; pi at the left -> pi/2.
    np.testing.assert_allclose(data.measurements[2:5, 2], [-math.pi / 2, 1.5708 - math.pi / 2, 2.5 - math.pi / 2],
                               atol=1e-15)
    # Scans: rows sharing a time, in time order.
    np.testing.assert_array_equal(data.scan_starts, [0, 2, 5, 6])
    np.testing.assert_array_equal(data.scan_times, [0.852, 1.0, 1.2])
    np.testing.assert_array_equal(data.scan(1)[:, 1], [7.5, 8.25, 9.0])
    assert data.scan(2).shape == (1, 4)


def test_scan_index_is_checked(tmp_path):
    data = read_victoria_park_acfr(write_run(tmp_path / "run"))
    for bad in (3, -1, 1.0, True, "0"):
        with pytest.raises(ValueError, match=r"index: a scan number in \[0, 3\)"):
            data.scan(bad)


def test_gps_is_optional_and_files_may_be_compressed(tmp_path):
    plain = read_victoria_park_acfr(write_run(tmp_path / "plain"))
    assert read_victoria_park_acfr(write_run(tmp_path / "nogps", gps=None)).gps is None
    packed = tmp_path / "packed"
    packed.mkdir()
    (packed / "inputs.dat.gz").write_bytes(gzip.compress(INPUTS.encode()))
    (packed / "measurements.dat.bz2").write_bytes(bz2.compress(MEASUREMENTS.encode()))
    (packed / "gps.dat.gz").write_bytes(gzip.compress(GPS.encode()))
    read = read_victoria_park_acfr(packed)
    for name in ("inputs", "measurements", "gps"):
        np.testing.assert_array_equal(getattr(read, name), getattr(plain, name))
    assert landmark_dataset_kind(packed) == "victoria_park_acfr"


def test_bad_rows_are_skipped_and_counted(tmp_path):
    """A few bad rows in a long file: skipped, each kind counted under its reason."""
    n = 400
    t = 0.025 * np.arange(n)
    lines = [f"{a:.3f} 1.0 0.01" for a in t]
    lines[10] = "0.250 1.0"                       # a field short
    lines[20] = "0.500 nan 0.01"                  # not finite
    lines[30] = "0.750 1.0 1.6"                   # steering beyond a right angle
    measurements = [f"{a:.3f} {5 + k % 7} {0.1 + 0.007 * k} 0.3" for k, a in enumerate(t)]
    measurements[5] = "0.125 -1 1.0 0.3"          # range not > 0
    measurements[6] = "0.150 4 3.5 0.3"           # bearing beyond pi
    measurements[7] = "0.175 4 1.0 -0.3"          # negative diameter
    measurements[8] = "0.200 4 one 0.3"           # a word
    data = read_victoria_park_acfr(write_run(tmp_path / "run", "\n".join(lines) + "\n",
                                             "\n".join(measurements) + "\n"))
    assert data.skipped_rows == {"inputs.dat: unreadable": 2, "inputs.dat: steering not in (-pi/2, pi/2)": 1,
                                 "measurements.dat: unreadable": 1, "measurements.dat: range not > 0": 1,
                                 "measurements.dat: bearing not in [0, pi] (the detector's angle across the scan)": 1,
                                 "measurements.dat: diameter < 0": 1}
    assert len(data.inputs) == n - 3 and len(data.measurements) == n - 4
    assert not np.isin([0.25, 0.5, 0.75], data.inputs[:, 0]).any()


def test_too_many_bad_rows_refuse_the_file_naming_the_first(tmp_path):
    n = 100  # two bad rows of 100: beyond MAX_BAD_ROW_FRACTION (1 %)
    assert MAX_BAD_ROW_FRACTION == 0.01
    lines = [f"{0.025 * k:.3f} 1.0 0.01" for k in range(n)]
    lines[40], lines[70] = "0 1 2.0", "0 1"
    write_run(tmp_path / "run", "\n".join(lines) + "\n")
    with pytest.raises(ValueError, match=r"inputs\.dat:41: steering not in .*\(2 of 100 rows skipped, more than "
                                         r"MAX_BAD_ROW_FRACTION = 0\.01\)"):
        read_victoria_park_acfr(tmp_path / "run")


def test_missing_empty_and_foreign_folders(tmp_path):
    with pytest.raises(FileNotFoundError, match="inputs.dat"):
        read_victoria_park_acfr(tmp_path)
    write_run(tmp_path / "run", measurements="")
    with pytest.raises(ValueError, match=r"measurements\.dat: no valid measurements\.dat rows"):
        read_victoria_park_acfr(tmp_path / "run")
    with pytest.raises(TypeError, match="folder: expected a file path"):
        read_victoria_park_acfr(3)
    (tmp_path / "other").mkdir()
    with pytest.raises(ValueError, match=r"folder without Barcodes.dat \(MRCLAM\) or inputs.dat and measurements.dat"):
        landmark_dataset_kind(tmp_path / "other")


def test_load_and_the_dataset_face(tmp_path):
    folder = write_run(tmp_path / "run")
    assert landmark_dataset_kind(folder) == "victoria_park_acfr"
    data = load_landmark_dataset(folder)
    assert isinstance(data, VictoriaParkAcfr)
    np.testing.assert_array_equal(victoria_park_acfr.start_pose(data),
                                  [-67.6493, -41.7142, math.radians(35.5)])
    assert np.all(victoria_park_acfr.start_pose(read_victoria_park_acfr(write_run(tmp_path / "b", gps=None))) == 0)
    with pytest.raises(TypeError, match="data"):
        victoria_park_acfr.start_pose(None)
    # Geometry as the README gives it: the laser 0.95 m ahead of the front axle.
    assert victoria_park_acfr.LASER_AHEAD == pytest.approx(3.78, abs=1e-12)
    far = MEASUREMENTS.replace("20.46202", f"{2 * ps._core.MAX_COORDINATE:g}")
    with pytest.raises(ValueError, match=r"run2: measurements\.dat ranges beyond .* \(MAX_COORDINATE\)"):
        victoria_park_acfr.load(write_run(tmp_path / "run2", measurements=far))


@pytest.mark.parametrize("text", [
    INPUTS,
    INPUTS.rstrip("\n"),                         # no final line end
    INPUTS.replace("\n", "\r\n"),                 # Windows line ends
    INPUTS.replace("\n", "\r"),                   # old Mac line ends
    "# t speed steering\n" + INPUTS,              # a comment
    INPUTS + "\n\n",                              # blank lines
    INPUTS.replace("0.512", "0.512 7"),           # a field too many
    INPUTS.replace("0.512", "inf"),               # not finite
    INPUTS.replace("0.512", "1_0"),               # float() takes it, the policy not
    INPUTS.replace("0.512", "\uff11"),            # a fullwidth digit: float() takes it
    INPUTS.replace("0.512", "0x1"),
    "1 2\n" + INPUTS,                            # the first row's count is not the table's
    "\xa0" + INPUTS,
])
def test_the_fast_parse_is_the_row_loop(tmp_path, text):
    """numeric_table (np.loadtxt on a clean file) gives what numeric_rows (the row policy) gives."""
    path = tmp_path / "t.dat"
    path.write_bytes(text.encode())
    fast, loop = numeric_table(str(path), 3, "t"), numeric_rows(str(path), (3,), "t")
    np.testing.assert_array_equal(fast.table, loop.table)
    np.testing.assert_array_equal(fast.lines, loop.lines)
    np.testing.assert_array_equal(fast.ordinals, loop.ordinals)
    assert (fast.skipped, fast.skipped_lines, fast.first_reason) == (loop.skipped, loop.skipped_lines,
                                                                     loop.first_reason)


def test_the_real_run(shared_data):
    folder = shared_data / "landmark_slam/victoria_park_acfr"
    if not folder.is_dir():
        pytest.skip(f"{folder} not present")
    data = load_landmark_dataset(folder)
    assert data.skipped_rows == {}
    # The README's figures: rows, scans, the time base.
    assert data.inputs.shape == (61945, 3) and data.measurements.shape == (52974, 4) and data.gps.shape == (4466, 3)
    assert len(data.scan_times) == 7230 and data.scan_starts[-1] == 52974
    assert data.inputs[0, 0] == 0.973 and data.scan_times[0] == 0.852 and data.gps[0, 0] == 0.0
    assert np.all(np.diff(data.inputs[:, 0]) > 0) and np.all(np.diff(data.scan_times) > 0)
    np.testing.assert_allclose(np.diff(data.inputs[:, 0]), 0.025, atol=1e-9)  # 40 Hz
    # Detections: 1-75 m, across the front half-plane.
    assert 1.0 < data.measurements[:, 1].min() and data.measurements[:, 1].max() < 76.0
    assert np.all(np.abs(data.measurements[:, 2]) < math.pi / 2)
    # Each row as the file has it, the bearing turned to the vehicle frame.
    raw = np.loadtxt(folder / "measurements.dat")
    np.testing.assert_array_equal(data.measurements[:, [0, 1, 3]], raw[:, [0, 1, 3]])
    np.testing.assert_allclose(data.measurements[:, 2], raw[:, 2] - math.pi / 2, rtol=0, atol=1e-15)
    # The start heading agrees with the GPS track: its first 20 m run within 1 deg of it.
    start = victoria_park_acfr.start_pose(data)
    away = data.gps[np.argmax(np.hypot(*(data.gps[:, 1:] - start[:2]).T) > 20.0), 1:] - start[:2]
    assert abs(math.atan2(away[1], away[0]) - victoria_park_acfr.START_HEADING) < math.radians(1.0)
