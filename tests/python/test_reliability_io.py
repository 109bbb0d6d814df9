"""Issue 12 in the file readers and the CLI's data handling: bounded sizes, regular files only,
ValueError("file:line: ...") whatever the bytes, real files with a few bad rows read (the rows
skipped, counted and reported), and property tests of the io API (``COVERED``)."""

import bz2
import gzip
import os
import pathlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import policy
import probslam as ps
from probslam import cli, io
from probslam.datasets import mrclam

#: io calls the property tests below drive with odd arguments.
COVERED = (
    "io.save_ros_map(grid, yaml_path, occupied_thresh, free_thresh)",
    "OccupancyGrid2D.save(path)",
    "OccupancyGrid3D.write_bt(path)",
    "io.read_mrclam(folder, robot)",
    "Mrclam.with_euclidean_ranges(scale)",
    "Mrclam.with_survey_swapped(pairs)",
    "datasets.mrclam.first_seconds(data, seconds)",
    "_core.parse_carmen_log(text)",
)

YAML = ("image: {image}\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
FLASER = "FLASER {n} {ranges} 0 0 0 0 0 0 {t} host {t}\n"
BARCODES = "# Subject Barcode\n1 5\n2 14\n6 9\n7 25\n"
LANDMARKS = "6 1.0 2.0 0 0\n7 3.0 -1.0 0 0\n"


def _flaser(n, t=1.0):
    return FLASER.format(n=n, ranges=" ".join(["1"] * n), t=t)


def _mrclam(folder, measurements, odometry="100 0.1 0\n101 0.1 0\n"):
    folder.mkdir(exist_ok=True)
    (folder / "Barcodes.dat").write_text(BARCODES)
    (folder / "Landmark_Groundtruth.dat").write_text(LANDMARKS)
    (folder / "Robot1_Odometry.dat").write_text(odometry)
    (folder / "Robot1_Measurement.dat").write_bytes(measurements)
    return folder


# --- 1. memory: sizes from input bounded before allocation ---------------------------------

def test_carmen_padding_is_bounded(tmp_path):
    """One 20000-beam scan among 2000 empty ones used to be padded to 2001 x 20000 (320 MB from
    a 200 kB file): the wide scan is skipped and counted, the rest read."""
    log = tmp_path / "wide.log"
    log.write_text(_flaser(20000) + "".join(_flaser(0, t=2.0 + k) for k in range(2000)))
    read = io.read_carmen_log(log)
    assert read.skipped_wide_scans == 1
    assert read.scans.ranges.shape == (2000, 0)


def test_carmen_mixed_real_widths_keep_every_scan(tmp_path):
    """A front (181) and a rear (361) laser pad by less than 2x: nothing skipped."""
    log = tmp_path / "two_lasers.log"
    log.write_text("".join(_flaser(181 if k % 2 else 361, t=k) for k in range(50)))
    read = io.read_carmen_log(log)
    assert read.skipped_wide_scans == 0 and read.scans.ranges.shape == (50, 361)
    assert np.isnan(read.scans.ranges[1, 181:]).all() and np.isfinite(read.scans.ranges[1, :181]).all()


def test_pgm_pixel_count_is_bounded(tmp_path):
    """A 20000 x 20000 image (a sparse file of 400 MB) is refused by the limit's name before
    allocating, not read into 1.6 GB of pixels."""
    (tmp_path / "m.yaml").write_text(YAML.format(image="big.pgm"))
    header = b"P5\n20000 20000\n255\n"
    with open(tmp_path / "big.pgm", "wb") as f:
        f.write(header)
        f.truncate(len(header) + 20000 * 20000)
    with pytest.raises(ValueError, match="kMaxMapPixels"):
        io.load_ros_map(tmp_path / "m.yaml")


def test_bt_leaf_expanding_to_many_voxels_is_refused(tmp_path):
    """14 bytes of tree can stand for 2^27 voxels (the import sets each): refused by name. The
    root's child 0 is an inner node, and so on down to depth 6, whose child 0 is a free leaf
    covering 2^9 voxels per axis; 8 nodes in all."""
    tree = b"\x03\x00" * 6 + b"\x01\x00"
    path = tmp_path / "big.bt"
    path.write_bytes(b"# Octomap OcTree binary file\nid OcTree\nsize 8\nres 0.5\ndata\n" + tree)
    with pytest.raises(ValueError, match="kMaxBtImportVoxels"):
        ps.OccupancyGrid3D.read_bt(str(path))


def test_compressed_log_size_is_bounded(tmp_path, monkeypatch):
    from probslam.io import _files
    monkeypatch.setattr(_files, "MAX_DECOMPRESSED_BYTES", 1000)
    path = tmp_path / "bomb.log.gz"
    path.write_bytes(gzip.compress(b"#" * 5000))
    with pytest.raises(ValueError, match="MAX_DECOMPRESSED_BYTES"):
        io.read_carmen_log(path)


# --- 2. files: regular files only, refused by name and at once -----------------------------

def _readers(tmp_path, bad):
    """(name, call) of every reader given the path `bad` where its main file should be."""
    yaml = tmp_path / "map.yaml"
    yaml.write_text(YAML.format(image=bad))
    mrclam = tmp_path / "mrclam"
    mrclam.mkdir()
    for name in ("Barcodes.dat", "Landmark_Groundtruth.dat", "Robot1_Odometry.dat"):
        os.symlink(bad, mrclam / name)
    acfr = tmp_path / "acfr"
    acfr.mkdir()
    for name in ("inputs.dat", "measurements.dat", "gps.dat"):
        os.symlink(bad, acfr / name)
    return [
        ("carmen", lambda: io.read_carmen_log(bad)),
        ("carmen_gz", lambda: io.read_carmen_log(_link(tmp_path, bad, "x.log.gz"))),
        ("ros_map_yaml", lambda: io.load_ros_map(bad)),
        ("ros_map_image", lambda: io.load_ros_map(yaml)),
        ("state_file", lambda: ps.OccupancyGrid2D.load(bad)),
        ("octomap_bt", lambda: ps.OccupancyGrid3D.read_bt(bad)),
        ("mrclam", lambda: io.read_mrclam(mrclam)),
        ("victoria_park", lambda: io.read_victoria_park(bad)),
        ("victoria_park_acfr", lambda: io.read_victoria_park_acfr(acfr)),
        ("positions", lambda: io.read_positions(bad)),
    ]


def _link(tmp_path, target, name):
    link = tmp_path / name
    if not link.exists():
        os.symlink(target, link)
    return link


@pytest.mark.parametrize("kind", ["directory", "device", "fifo"])
def test_readers_refuse_what_is_not_a_regular_file(tmp_path, kind):
    if kind == "directory":
        bad = tmp_path / "adir"
        bad.mkdir()
    elif kind == "device":
        bad = pathlib.Path("/dev/zero")
    else:
        bad = tmp_path / "fifo"
        os.mkfifo(bad)  # opening it would block until a writer came
    for name, call in _readers(tmp_path, str(bad)):
        with pytest.raises(ValueError, match="not a regular file"):
            call()


def test_missing_files_raise_file_not_found_naming_the_file(tmp_path):
    missing = tmp_path / "missing.xyz"
    for call in [io.read_carmen_log, io.read_victoria_park, io.load_ros_map, ps.OccupancyGrid2D.load, ps.read_pose_graph,
                 ps.graph.read_pose_graph, ps.OccupancyGrid3D.read_bt, lambda p: ps.OccupancyGrid3D.read_bt(str(p))]:
        with pytest.raises(FileNotFoundError, match="missing.xyz"):
            call(missing)
    with pytest.raises(FileNotFoundError, match="Barcodes.dat"):
        io.read_mrclam(tmp_path)


@pytest.mark.parametrize("value", [None, 3.5, ["a.log"]])
def test_readers_and_writers_name_a_path_argument_that_is_not_a_path(tmp_path, value):
    grid = ps.OccupancyGrid2D(0.1, 4, 4)
    calls = [("path", io.read_carmen_log), ("path", io.read_victoria_park), ("folder", io.read_mrclam),
             ("folder", io.read_victoria_park_acfr), ("path", io.read_positions),
             ("yaml_path", io.load_ros_map), ("path", ps.OccupancyGrid2D.load), ("path", ps.graph.read_pose_graph),
             ("path", ps.eval.read_relations), ("yaml_path", lambda p: io.save_ros_map(grid, p)),
             ("path", lambda p: grid.save(p)), ("path", lambda p: io.write_png(grid, p)),
             ("path", lambda p: ps.slam.write_trajectory(np.zeros(1), np.zeros((1, 3)), p)),
             ("relations", lambda r: ps.eval.relations_error(np.arange(2.0), np.zeros((2, 3)), r)),
             ("path", io.read_rosbag), ("path", lambda p: io.write_rosbag(io.LaserScans(*[np.zeros((1, 3))] * 8), p))]
    for name, call in calls:
        with pytest.raises(TypeError, match=f"^{name}: expected a"):
            call(value)
    assert not list(tmp_path.iterdir())


# --- 3. unclear errors: any bytes give ValueError("file:line: ...") --------------------------

BAD_BYTES = b"\xff\xfe\x80"


@pytest.mark.parametrize("suffix, opener", [(".log", open), (".log.gz", gzip.open), (".log.bz2", bz2.open)])
def test_carmen_non_utf8_bytes(tmp_path, suffix, opener):
    path = tmp_path / ("bad" + suffix)
    with opener(path, "wb") as f:
        f.write(b"ODOM 0 0 0 0 0 0 1\nFLASER 2 1 " + BAD_BYTES + b" 0 0 0 0 0 0 2\n")
    with pytest.raises(ValueError, match=r"bad\.log.*:2: .*\\xff") as info:
        io.read_carmen_log(path)
    assert not isinstance(info.value, UnicodeError)


def test_carmen_param_value_with_non_utf8_bytes_is_kept_escaped(tmp_path):
    path = tmp_path / "p.log"
    path.write_bytes(b"PARAM robot_name r" + BAD_BYTES + b"b nohost 0\n" + _flaser(2).encode())
    assert io.read_carmen_log(path).params["robot_name"] == "r\\xff\\xfe\\x80b"


def test_yaml_and_bt_header_non_utf8_bytes(tmp_path):
    (tmp_path / "m.yaml").write_bytes(YAML.format(image="m.pgm").replace("0.1", "0.\xff").encode("latin-1"))
    with pytest.raises(ValueError, match=r"m\.yaml:2: .*\\xff") as info:
        io.load_ros_map(tmp_path / "m.yaml")
    assert not isinstance(info.value, UnicodeError)
    (tmp_path / "t.bt").write_bytes(b"# Octomap OcTree binary file\nid Oc" + BAD_BYTES + b"\nsize 1\nres 0.1\ndata\n")
    with pytest.raises(ValueError, match=r"t\.bt: .*\\xff") as info:
        ps.OccupancyGrid3D.read_bt(str(tmp_path / "t.bt"))
    assert not isinstance(info.value, UnicodeError)


def test_mrclam_and_victoria_park_non_utf8_bytes(tmp_path):
    folder = _mrclam(tmp_path / "m", b"100.2 9 2.1 0.3\n100.3 " + BAD_BYTES + b" 2.1 0.3\n")
    with pytest.raises(ValueError, match=r"Robot1_Measurement\.dat:2: .*\\xff") as info:
        io.read_mrclam(folder)
    assert not isinstance(info.value, UnicodeError)
    vp = tmp_path / "vp.txt"
    vp.write_bytes(b"ODOMETRY 0 1 1 0 0 10 0 0 10 0 31.6\nLANDMARK 1 " + BAD_BYTES + b" 2 1 1.6 0 1.6\n")
    with pytest.raises(ValueError, match=r"vp\.txt:2:") as info:
        io.read_victoria_park(vp)
    assert not isinstance(info.value, UnicodeError)


@pytest.mark.parametrize("suffix, compress", [(".log.gz", gzip.compress), (".clf.bz2", bz2.compress)])
def test_corrupt_compressed_log_names_the_file(tmp_path, suffix, compress):
    data = compress(_flaser(3).encode() * 50)
    for name, bytes_ in [("cut", data[:len(data) // 2]), ("flipped", data[:20] + bytes([data[20] ^ 0xFF]) + data[21:]),
                         ("garbage", b"not compressed at all")]:
        path = tmp_path / (name + suffix)
        path.write_bytes(bytes_)
        with pytest.raises(ValueError, match=name):
            io.read_carmen_log(path)


# --- 4. real data: a few bad rows are skipped, counted and reported ------------------------

def test_mrclam_stray_barcodes_skipped_and_counted(tmp_path):
    folder = _mrclam(tmp_path / "m", b"100.2 9 2.1 0.3\n100.3 77 1.0 0.0\n100.4 25 3.0 -0.2\n")
    data = io.read_mrclam(folder)
    np.testing.assert_array_equal(data.measurements[:, 1], [6, 7])
    assert data.skipped_rows == {"Robot1_Measurement.dat: barcode not in Barcodes.dat": 1}


def test_mrclam_a_few_unreadable_rows_are_skipped_but_many_are_fatal(tmp_path):
    odometry = "".join(f"{100 + 0.01 * k:.2f} 0.1 0\n" for k in range(300))
    folder = _mrclam(tmp_path / "m", b"100.2 9 2.1 0.3\n", odometry + "100.5 0.1\n")  # a line cut short
    data = io.read_mrclam(folder)
    assert len(data.odometry) == 300 and data.skipped_rows == {"Robot1_Odometry.dat: unreadable": 1}
    folder = _mrclam(tmp_path / "m", b"100.2 9 2.1 0.3\n", odometry + "100.5 0.1\n" * 10)
    with pytest.raises(ValueError, match=r"Robot1_Odometry\.dat:301: .*MAX_BAD_ROW_FRACTION"):
        io.read_mrclam(folder)
    (folder / "Barcodes.dat").write_text(BARCODES + "8 inf\n")  # the map's key table is strict
    with pytest.raises(ValueError, match=r"Barcodes\.dat:6:"):
        io.read_mrclam(folder)


def test_victoria_park_singular_noise_record_repaired(tmp_path):
    good = "".join(f"ODOMETRY {k} {k + 1} 1 0 0 10 0 0 10 0 31.6\n" for k in range(200))
    path = tmp_path / "vp.txt"
    path.write_text(good + "LANDMARK 3 7 2 1 0 0 1.6\n")  # R singular: information R^T R only PSD
    data = io.read_victoria_park(path)
    # Repaired, not skipped (docs/pose_graphs.md, "Information repair"): the zero eigenvalue raised
    # to the floor, so the sighting keeps its y information and is nearly uninformative in x.
    assert data.repaired_rows == 1 and data.skipped_rows == 0 and len(data.pose_from) == 200 and len(data.xy) == 1
    floor = ps.graph.INFORMATION_EIGENVALUE_FLOOR * 1.6 ** 2
    assert np.allclose(np.linalg.inv(data.xy_cov[0]), np.diag([floor, 1.6 ** 2]))


def test_victoria_park_skips_records_through_the_graph_reader(tmp_path):
    good = "".join(f"ODOMETRY {k} {k + 1} 1 0 0 10 0 0 10 0 31.6\n" for k in range(200))
    path = tmp_path / "vp.txt"
    path.write_text(good + "LANDMARK 3 7 2 1 1 0 1\nLANDMARK 3 8 2\nVERTEX2 1 2\n")  # cut line, foreign record
    data = io.read_victoria_park(path)
    assert data.skipped_rows == 2 and len(data.pose_from) == 200 and list(data.landmark) == [7]
    path.write_text(good + "LANDMARK 3 8 2\nVERTEX2 1 2\nLANDMARK 1 1\n")  # 3 of 203: too many
    with pytest.raises(ValueError, match=r"vp\.txt:201: .*3 of 203 rows unreadable"):
        io.read_victoria_park(path)


def test_pose_graph_skipped_rows_with_non_utf8_bytes_are_reported_escaped(tmp_path):
    path = tmp_path / "g.txt"
    path.write_bytes(b"".join(b"ODOMETRY %d %d 1 0 0 10 0 0 10 0 31.6\n" % (k, k + 1) for k in range(200))
                     + b"LANDMARK 1 " + BAD_BYTES + b" 2 1 1.6 0 1.6\n")
    read = ps.graph.read_pose_graph_with_report(path)
    assert read.report.skipped_rows == 1 and read.report.skipped_lines == [201]
    assert "\\xff\\xfe\\x80" in read.report.skipped_reasons[0] and read.graph.num_point_edges == 0


def test_carmen_bad_lines_with_non_utf8_bytes_are_skipped_and_reported_escaped(tmp_path):
    path = tmp_path / "log.clf"
    path.write_bytes(_flaser(3).encode() + b"FLASER 2 1 " + BAD_BYTES + b" 0 0 0 0 0 0 2\n" + BAD_BYTES + b" 1 2\n"
                     + _flaser(3, t=3.0).encode())
    with pytest.warns(UserWarning, match=r"skipped 2 malformed lines \(lines 2, 3; first: .*\\xff"):
        log = io.read_carmen_log(path)
    assert len(log.scans) == 2 and log.skipped_rows == 2 and log.skipped_lines == [2, 3]
    assert all("\\xff\\xfe\\x80" in reason for reason in log.skipped_reasons)


MRCLAM_SKIPPED = {("mrclam_dataset1", 3): 2, ("mrclam_dataset1", 5): 1, ("mrclam_dataset7", 3): 9}


@pytest.mark.slow
def test_cli_ekf_slam_runs_on_every_mrclam_robot(shared_data, tmp_path, capsys):
    """Every robot of every shipped MRCLAM dataset, the first 30 s of each (the whole file is
    read, so the stray barcodes are all counted), reporting the rows skipped."""
    folders = sorted((shared_data / "landmark_slam").glob("mrclam_dataset*"))
    assert folders
    for folder in folders:
        for robot in range(1, 6):
            if not (folder / f"Robot{robot}_Measurement.dat").exists():
                continue
            code = cli.main(["ekf-slam", str(folder), "--robot", str(robot), "--seconds", "30",
                             "-o", str(tmp_path / "out")])
            out = capsys.readouterr().out
            assert code == 0, (folder.name, robot, out)
            skipped = MRCLAM_SKIPPED.get((folder.name, robot), 0)
            expected = (f"skipped rows:  {skipped} (Robot{robot}_Measurement.dat: barcode not in Barcodes.dat: "
                        f"{skipped})") if skipped else "skipped rows:  0"
            assert expected in out, out


# --- 6. property tests ---------------------------------------------------------------------

@settings(max_examples=40, deadline=None)
@given(occupied=policy.floats(), free=policy.floats())
def test_save_ros_map_thresholds(tmp_path_factory, occupied, free):
    grid = ps.OccupancyGrid2D(0.1, 4, 3)
    grid.log_odds[:] = np.linspace(-3, 3, 12).reshape(3, 4)
    folder = tmp_path_factory.mktemp("ros")
    raised, _ = policy.check_call(lambda: io.save_ros_map(grid, folder / "m.yaml", occupied, free))
    if not raised:
        back = io.load_ros_map(folder / "m.yaml")
        assert back.same_geometry(grid) and np.all(np.isfinite(back.log_odds))


def test_ros_map_with_a_subnormal_threshold_reads_back(tmp_path):
    """Hypothesis found it: free_thresh 5e-324 was written, then refused on loading ("not a
    number": the reader's stod throws on underflow)."""
    grid = ps.OccupancyGrid2D(0.1, 4, 3)
    grid.log_odds[:] = np.linspace(-3, 3, 12).reshape(3, 4)
    io.save_ros_map(grid, tmp_path / "m.yaml", 0.65, 5e-324)
    back = io.load_ros_map(tmp_path / "m.yaml")
    assert back.same_geometry(grid) and np.all(np.isfinite(back.log_odds))


@settings(max_examples=20, deadline=None)
@given(thresh=policy.odd_objects())
def test_save_ros_map_odd_objects(tmp_path_factory, thresh):
    grid = ps.OccupancyGrid2D(0.1, 2, 2)
    policy.check_call(lambda: io.save_ros_map(grid, tmp_path_factory.mktemp("ros") / "m.yaml", thresh))


@pytest.mark.parametrize("where", ["missing_dir/x", "", "adir", "/dev/null/x"])
def test_writers_with_bad_paths_raise_cleanly(tmp_path, where):
    (tmp_path / "adir").mkdir()
    path = str(tmp_path / where) if where and not where.startswith("/") else where
    grid, grid3 = ps.OccupancyGrid2D(0.1, 2, 2), ps.OccupancyGrid3D(0.1)
    for call in (lambda: grid.save(path), lambda: io.save_ros_map(grid, path),
                 lambda: grid3.write_bt(str(path))):
        with pytest.raises((ValueError, OSError, RuntimeError)):
            call()


def _small_mrclam():
    landmarks = np.array([[6, 1.0, 2.0], [7, 3.0, -1.0]])
    measurements = np.array([[100.2, 6, 2.1, 0.3], [100.3, 7, 1.0, -0.2]])
    return io.Mrclam(np.array([[100.0, 0.1, 0.0], [101.0, 0.1, 0.0]]), measurements, None, landmarks, 0)


@settings(max_examples=40, deadline=None)
@given(scale=st.one_of(policy.floats(), policy.odd_objects()))
def test_with_euclidean_ranges_odd_scales(scale):
    data = _small_mrclam()
    policy.check_call(lambda: data.with_euclidean_ranges(scale).measurements,
                      snapshot=lambda: policy.state_of(data, "measurements"))


@settings(max_examples=30, deadline=None)
@given(pairs=st.one_of(policy.odd_objects(), st.lists(st.tuples(st.integers(-5, 20), st.integers(-5, 20)),
                                                       max_size=3)))
def test_with_survey_swapped_odd_pairs(pairs):
    data = _small_mrclam()
    policy.check_call(lambda: data.with_survey_swapped(pairs).landmarks,
                      snapshot=lambda: policy.state_of(data, "landmarks"))


@settings(max_examples=30, deadline=None)
@given(seconds=st.one_of(policy.floats(), policy.odd_objects()))
def test_first_seconds_odd_windows(seconds):
    data = _small_mrclam()
    policy.check_call(lambda: mrclam.first_seconds(data, seconds).odometry,
                      snapshot=lambda: policy.state_of(data, "odometry", "measurements"))


@settings(max_examples=15, deadline=None)
@given(robot=st.one_of(st.integers(-3, 8), policy.odd_objects(), st.just(True), st.just(2.0)))
def test_read_mrclam_odd_robot_numbers(tmp_path_factory, robot):
    folder = _mrclam(tmp_path_factory.mktemp("m") / "m", b"100.2 9 2.1 0.3\n")

    def read():
        try:
            return io.read_mrclam(folder, robot)
        except FileNotFoundError:  # documented: a robot number without files
            return "no files"

    raised, result = policy.check_call(read, finite=False)
    assert raised or robot == 1 or result == "no files"


TOKENS = st.sampled_from(["FLASER", "ROBOTLASER1", "ODOM", "PARAM", "0", "1", "2", "3", "-1", "1e308", "nan",
                          "inf", "1000001", "0.5", "x", "\xff", "#"])


@settings(max_examples=60, deadline=None)
@given(lines=st.lists(st.lists(TOKENS, max_size=14).map(" ".join), max_size=8))
def test_parse_carmen_log_token_soup(lines):
    try:
        ps._core.parse_carmen_log("\n".join(lines))
    except ValueError as error:
        assert not isinstance(error, UnicodeError) and ":" in str(error)
