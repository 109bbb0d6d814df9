"""Seed corpora for the fuzz targets.

``python fuzz/make_seeds.py committed`` rewrites fuzz/seeds/<target>/ (small self-written
files, committed); ``python fuzz/make_seeds.py shared DIR`` writes seeds cut from the real files
of /work/shared/data (or $PROBSLAM_SHARED_DATA) into DIR/<target>/, at most MAX_SEED_BYTES each
and cut at a line end, when the data is present (fuzz.sh does this at run time).
"""

from __future__ import annotations

import bz2
import gzip
import os
import pathlib
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from targets import MRCLAM_FILES, RAW_STATE, SEPARATOR, STATE_CLASSES, VICTORIA_PARK_ACFR_FILES, state_payload  # noqa: E402

#: Larger seeds slow every execution (libFuzzer's -max_len follows the largest seed).
MAX_SEED_BYTES = 4096
HERE = pathlib.Path(__file__).resolve().parent

CARMEN = b"""# tiny log
PARAM laser_front_laser_resolution 1.0 nohost 0
ODOM 0 0 0 0 0 0 1.0 host 1.0
FLASER 4 1.0 2.0 3.0 4.0 0.5 0.1 0.2 0.5 0.1 0.2 2.0 host 2.0
ROBOTLASER1 0 -1.57 3.14 0.785 30 0.01 0 5 1 2 3 4 5 0 0.5 0.1 0.2 0.5 0.1 0.2 0 0 0 0 0 3.0 host 3.0
FLASER 3 1.5 2.5 81.83 0.6 0.1 0.25 0.6 0.1 0.25 4.0 host 4.0
"""
G2O = b"""VERTEX_SE2 0 0 0 0
VERTEX_SE2 1 1 0 0.1
VERTEX_XY 2 1 1
EDGE_SE2 0 1 1 0 0.1 100 0 0 100 0 1000
EDGE_SE2_XY 1 2 0 1 10 0 10
FIX 0
"""
TORO = b"""VERTEX2 0 0 0 0
VERTEX2 1 1 0 0
VERTEX2 2 2 0 0
EDGE2 0 1 1 0 0 100 0 100 1000 0 0
EDGE2 1 2 1 0 0 100 0 100 1000 0 0
EDGE2 0 2 2 0 0 100 0 100 1000 0 0
"""
#: TORO with EQUIV chains (both directions, a chain closing on itself, an edge inside one).
TORO_EQUIV = TORO + b"""VERTEX2 3 0.1 0 0
VERTEX2 4 1.1 0 0
VERTEX2 5 2.1 0 0
EDGE2 2 3 -2 0 0 100 0 100 1000 0 0
EDGE2 3 4 1 0 0 100 0 100 1000 0 0
EDGE2 4 5 1 0 0 100 0 100 1000 0 0
EQUIV 3 0
EQUIV 4 3
EQUIV 1 4
EQUIV 5 2
"""
#: TORO 3-D: VERTEX3 / EDGE3 id x y z roll pitch yaw and 21 information entries.
TORO_3D = b"""VERTEX3 0 0 0 0 0 0 0
VERTEX3 1 1 0 0 0 0 0.1
VERTEX3 2 2 0 0 0 0 0.2
EDGE3 0 1 1 0 0 0 0 0.1 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400
EDGE3 1 2 1 0 0 0 0 0.1 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400
"""
ISAM = b"""ODOMETRY 0 1 1 0 0 10 0 0 10 0 31.6
ODOMETRY 1 2 1 0 0.1 10 0 0 10 0 31.6
LANDMARK 1 5 2 1 1.6 0 1.6
LANDMARK 2 5 1 1 1.6 0 1.6
LANDMARK 2 1 1 -1 1.6 0 1.6
"""
G2O_3D = b"""VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1
VERTEX_SE3:QUAT 1 1 0 0 0 0 0.0998334 0.9950042
FIX 0
PARAMS_SE3OFFSET 0 0 0 0 0 0 0 1
EDGE_SE3_PRIOR 1 0 1 0 0 0 0 0.0998334 0.9950042 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 4 0 0 4 0 4
EDGE_SE3:QUAT 0 1 1 0 0 0 0 0.0998334 0.9950042 100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400
"""
#: Points seen through two sensor offsets (PARAMS_SE3OFFSET, EDGE_SE3_TRACKXYZ).
G2O_3D_POINTS = G2O_3D + b"""PARAMS_SE3OFFSET 1 0.1 0 0.2 0 0 0.0998334 0.9950042
VERTEX_TRACKXYZ 7 2 1 0
EDGE_SE3_TRACKXYZ 0 7 0 2 1 0 10 0 0 10 0 10
EDGE_SE3_TRACKXYZ 1 7 1 1 1 -0.2 10 0 0 10 0 10
"""
#: An edge whose information has a negative eigenvalue (cubicle.g2o's kind): repaired, counted.
G2O_3D_NEGATIVE = G2O_3D.replace(b"100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 400",
                                 b"100 0 0 0 0 0 100 0 0 0 0 100 0 0 0 400 0 0 400 0 -3")
ISAM_3D = b"""EDGE3 0 1 1 0 0 0 0 0.2 10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 100 0 0 100 0 25
EDGE3 1 2 1 0 0 0.01 0 0.2 10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 100 0 0 100 0 25
EDGE3 0 2 2 0 0.1 0 0 0.4 10 0 0 0 0 0 10 0 0 0 0 10 0 0 0 100 0 0 100 0 25
"""
VICTORIA = b"""ODOMETRY 0 1 1 0 0 10 0 0 10 0 31.6
ODOMETRY 1 2 1 0 0.1 10 0 0 10 0 31.6
LANDMARK 1 7 2 1 1.6 0 1.6
LANDMARK 2 7 1 1 1.6 0 1.6
"""
MRCLAM = [b"# Subject # Barcode #\n1 5\n2 14\n6 9\n7 25\n8 88\n",
          b"# Subject # x # y # sx # sy\n6 1.0 2.0 0.001 0.001\n7 3.0 -1.0 0.001 0.001\n8 0 0 0.001 0.001\n",
          b"# Time # v # w\n100.0 0.1 0.0\n100.5 0.1 0.1\n101.0 0.0 0.0\n",
          b"# Time # Barcode # Range # Bearing\n100.2 9 2.1 0.3\n100.2 25 3.0 -0.2\n100.7 14 1.0 0.0\n"
          b"100.8 77 1.0 0.0\n",
          b"# Time # x # y # theta\n100.0 0 0 0\n101.0 0.1 0 0.05\n"]
VICTORIA_ACFR = [b"     0.973      0.000    -0.0035\n     0.998      0.512    -0.0042\n"
                 b"     1.023      1.250     0.3100\n",
                 b"     0.852   20.46202    0.88575    0.35404\n     0.852   29.59859    1.02102    0.25717\n"
                 b"     1.000    7.50000    0.00000    0.20000\n",
                 b"     0.000     -67.6493     -41.7142\n     1.001     -67.7310     -41.6681\n",
                 b"# t x y\n0.5 1.0 2.0\n1.5 1.1 2.2\n"]
RELATIONS = b"""# t1 t2 x y z roll pitch yaw
90.239599 90.719599 0.422330 -0.000750 0.000000 0.000000 0.000000 0.017260
90.719599 91.321399 0.213430 -0.014750 0.000000 0.000000 0.000000 -0.405780
94.3996 94.7596 0.2771 0.06383 0 0 0 0.09774  # a comment
"""
YAML = b"image: map.pgm\nmode: trinary\nresolution: 0.05\norigin: [-1.0, 2.0, 0.0]\nnegate: 0\n" \
       b"occupied_thresh: 0.65\nfree_thresh: 0.196\n"


def _write(folder: pathlib.Path, name: str, data: bytes) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)


def small_states() -> dict:
    """One small object of every class with a state file, by tag, each part way through a run
    (so that every list in its state holds entries): the state_file target's seeds."""
    import probslam as ps
    from probslam import _core, cli, io
    from probslam.ekf import EkfSlam, MultiHypothesisEkfSlam

    grid = ps.OccupancyGrid2D(0.25, 24, 20, origin=(-3.0, -2.5))
    grid.log_odds[:] = -2.0
    grid.log_odds[[0, -1], :] = grid.log_odds[:, [0, -1]] = 3.0
    grid3 = ps.OccupancyGrid3D(0.5)
    grid3.insert_point_cloud(np.array([[1.0, 0.5, 0.2], [0.6, -0.4, 0.1]]), np.zeros(3))
    graph = ps.PoseGraph2D()
    for k in range(3):
        graph.add_pose(k, (k, 0.1 * k, 0.0))
    graph.add_point(9, (1.0, 2.0))
    graph.add_pose_edge(0, 1, (1.0, 0.1, 0.0), np.eye(3))
    graph.add_pose_edge(1, 2, (1.0, 0.1, 0.0), np.eye(3))
    graph.add_point_edge(1, 9, (0.0, 1.9), np.eye(2))
    graph3 = ps.PoseGraph3D()
    for k in range(3):
        graph3.add_pose(k, (k, 0.0, 0.1 * k, 0.0, 0.0, 0.0, 1.0))
    graph3.add_point(9, (1.0, 2.0, 0.5))
    graph3.add_pose_edge(0, 1, (1.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0), np.eye(6))
    graph3.add_pose_edge(1, 2, (1.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0), np.eye(6))
    graph3.add_pose_prior(0, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0), np.eye(6))
    graph3.add_point_edge(1, 9, (0.0, 2.0, 0.4), np.eye(3))
    # Laser SLAM on the bundled log's first scans, few beams and coarse cells: a small state with
    # several submaps, constraints and particles.
    scans = io.read_carmen_log(ps.data.path(cli.BUNDLED_RAW_LOG)).scans
    rows, beams = slice(0, 400, 8), slice(None, None, 12)
    ranges, angles, odometry = scans.ranges[rows, beams], scans.beam_angles()[rows, beams], scans.laser_poses[rows]
    slam = ps.SubmapSlam2D(frontend=dict(resolution=1.0, filter={"max_usable_range": 5.0}, submap_scans=8))
    slam.add_scans(ranges, angles, odometry, scans.timestamps[rows])
    ism = ps.IncrementalScanMatcher(resolution=1.0, filter={"max_usable_range": 5.0}, submap_scans=8)
    ism.add_scans(ranges, angles, odometry, scans.timestamps[rows])
    rbpf = ps.GridFastSlam(num_particles=2, resolution=1.0, filter={"max_usable_range": 5.0})
    rbpf.add_scans(ranges, angles, odometry, scans.timestamps[rows])
    fast = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001]), num_particles=3, seed=3)
    ekf = EkfSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001]))
    mht = MultiHypothesisEkfSlam(EkfSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.0025, 0.0001])))
    z = np.array([[2.0, 0.3], [3.0, -0.4]])
    for _ in range(2):
        fast.predict(0.3, 0.1, 1.0)
        fast.update_unknown(z)
        ekf.predict(0.3, 0.1, 1.0)
        ekf.update_unknown(z)
        mht.predict(0.3, 0.1, 1.0)
        mht.update(z)
    mcl = ps.MonteCarloLocalization(grid, min_particles=20, max_particles=40, seed=5)
    mcl.update(np.full(8, 2.0), np.linspace(-1.5, 1.5, 8))
    mcl.predict_odometry((0.3, 0.0, 0.1))
    states = {"OccupancyGrid2D": grid, "OccupancyGrid3D": grid3, "PoseGraph2D": graph, "PoseGraph3D": graph3,
              "SubmapSlam2D": slam, "GridFastSlam": rbpf, "FastSlam": fast, "EkfSlam": ekf,
              "MultiHypothesisEkfSlam": mht, "MonteCarloLocalization": mcl, "IncrementalScanMatcher": ism}
    assert tuple(states) == STATE_CLASSES
    return states


def state_bytes(obj) -> bytes:
    """The C++ state file of obj (the Python EKF classes pickle the one they wrap)."""
    s = obj.__getstate__()
    return s if isinstance(s, bytes) else next(iter(s.values())).__getstate__()


def _state_seeds(out: pathlib.Path) -> None:
    """The state_file target's seeds: a class byte, then a payload (framed with a valid checksum
    by the target), for every class; and two whole files (header mutations)."""
    for index, (tag, obj) in enumerate(small_states().items()):
        framed = state_bytes(obj)
        _write(out / "state_file", f"{tag}.bin", bytes([index]) + state_payload(framed)[1])
        if tag in ("OccupancyGrid2D", "PoseGraph2D"):
            _write(out / "state_file", f"{tag}_file.bin", bytes([RAW_STATE + index]) + framed)


def _library_files(out: pathlib.Path) -> None:
    """Seeds the library writes itself: a map_server map, two .bt trees, a learned model."""
    import probslam as ps
    from probslam import io
    with tempfile.TemporaryDirectory() as tmp:
        grid = ps.OccupancyGrid2D(0.1, 5, 3, origin=(-0.2, 0.3))
        grid.log_odds[:] = np.arange(15.0).reshape(3, 5) - 7
        io.save_ros_map(grid, os.path.join(tmp, "m.yaml"))
        yaml = pathlib.Path(tmp, "m.yaml").read_bytes().replace(b"m.pgm", b"map.pgm")
        _write(out / "ros_map", "trinary.bin", yaml + SEPARATOR + pathlib.Path(tmp, "m.pgm").read_bytes())
        _write(out / "ros_map", "p2_scale.bin", YAML.replace(b"trinary", b"scale") + SEPARATOR +
               b"P2\n# comment\n3 2\n255\n0 128 254\n205 10 255\n")
        g3 = ps.OccupancyGrid3D(0.2)
        g3.insert_point_cloud(np.array([[1.0, 0.5, 0.2], [0.6, -0.4, 0.1]]), np.zeros(3))
        g3.write_bt(os.path.join(tmp, "t.bt"))
        _write(out / "octomap_bt", "rays.bt", pathlib.Path(tmp, "t.bt").read_bytes())
        g3 = ps.OccupancyGrid3D(0.5)
        g3.insert_point_cloud(np.array([[3.0, 0.0, 0.0]]), np.zeros(3))
        g3.write_bt(os.path.join(tmp, "t.bt"))
        _write(out / "octomap_bt", "line.bt", pathlib.Path(tmp, "t.bt").read_bytes())
        model = ps.LearnedInverseModel(hidden=2)
        model.weights = np.linspace(-1.0, 1.0, model.n_weights(7))
        model.mean, model.scale, model.prior = np.zeros(7), np.ones(7), 0.25
        model.save(os.path.join(tmp, "m.npz"))
        _write(out / "learned_model", "hidden2.npz", pathlib.Path(tmp, "m.npz").read_bytes())


def committed(out: pathlib.Path = HERE / "seeds") -> None:
    _write(out / "carmen", "tiny.log", CARMEN)
    _write(out / "carmen_gz", "tiny.log.gz", gzip.compress(CARMEN, mtime=0))
    _write(out / "g2o", "tiny.g2o", G2O)
    _write(out / "toro", "tiny.graph", TORO)
    _write(out / "isam", "tiny.txt", ISAM)
    _write(out / "g2o_3d", "tiny.g2o", G2O_3D)
    _write(out / "isam_3d", "tiny.txt", ISAM_3D)
    _write(out / "toro_3d", "tiny.graph", TORO_3D)
    _write(out / "toro_equiv", "chains.graph", TORO_EQUIV)
    _write(out / "g2o_3d_graph", "tiny.g2o", G2O_3D)
    _write(out / "g2o_3d_graph", "points.g2o", G2O_3D_POINTS)
    _write(out / "g2o_3d_graph", "negative_information.g2o", G2O_3D_NEGATIVE)
    _write(out / "victoria_park", "tiny.txt", VICTORIA)
    _write(out / "mrclam", "tiny.bin", SEPARATOR.join(MRCLAM))
    _write(out / "victoria_park_acfr", "tiny.bin", SEPARATOR.join(VICTORIA_ACFR))
    _write(out / "relations", "tiny.relations", RELATIONS)
    _write(out / "relations", "tiny.relations.gz", gzip.compress(RELATIONS, mtime=0))
    _write(out / "relations", "tiny.relations.bz2", bz2.compress(RELATIONS))
    _library_files(out)
    _state_seeds(out)


def _head(data: bytes) -> bytes:
    """At most MAX_SEED_BYTES, cut after a line end."""
    if len(data) <= MAX_SEED_BYTES:
        return data
    cut = data.rfind(b"\n", 0, MAX_SEED_BYTES)
    return data[:cut + 1 if cut > 0 else MAX_SEED_BYTES]


def _open(path: pathlib.Path) -> bytes:
    opener = gzip.open if path.suffix == ".gz" else bz2.open if path.suffix == ".bz2" else open
    with opener(path, "rb") as f:
        return f.read(8 * MAX_SEED_BYTES)


def shared(out: pathlib.Path, data: pathlib.Path) -> int:
    """Seeds cut from the shared data; returns how many were written (0 without the data)."""
    if not data.is_dir():
        return 0
    count = 0

    def add(target: str, name: str, content: bytes) -> None:
        nonlocal count
        _write(out / target, name, content)
        count += 1

    for log in sorted(data.glob("laser_2d/*/*")):
        if log.suffix in (".gz", ".bz2", ".clf", ".log"):
            head = _head(_open(log))
            add("carmen", log.name.split(".")[0] + ".log", head)
            add("carmen_gz", log.name.split(".")[0] + ".log.gz", gzip.compress(head, mtime=0))
    for graph in sorted(data.glob("pose_graphs/*/*")):
        target = {".g2o": "g2o", ".graph": "toro"}.get(graph.suffix)
        if target:
            add(target, graph.name, _head(_open(graph)))
        if graph.suffix == ".graph":
            add("toro_equiv", graph.name, _head(_open(graph)))
        head = _head(_open(graph)) if graph.suffix in (".g2o", ".txt") else b""
        if head.startswith(b"VERTEX_SE3:QUAT"):  # 3-D g2o (pose3example.txt among them)
            add("g2o_3d", graph.name, head)
            add("g2o_3d_graph", graph.name, head)
        elif head.startswith(b"EDGE3"):  # iSAM 3-D (sphere2500.txt)
            add("isam_3d", graph.name, head)
    for rel in sorted(data.glob("laser_2d/*/*.relations")):
        add("relations", rel.name, _head(_open(rel)))
    vp = data / "landmark_slam/victoria_park"
    for name in ("victoriaPark.txt", "victoria_park_gtsam.txt"):
        if (vp / name).exists():
            add("isam", name, _head(_open(vp / name)))
            add("victoria_park", name, _head(_open(vp / name)))
    acfr = data / "landmark_slam/victoria_park_acfr"
    if acfr.is_dir():
        parts = [_head(_open(acfr / name)) for name in VICTORIA_PARK_ACFR_FILES]
        add("victoria_park_acfr", "victoria_park_acfr.bin", SEPARATOR.join(parts + parts[-1:]))
    for folder in sorted(data.glob("landmark_slam/mrclam_dataset*")):
        for robot in (1, 3):
            files = [f.replace("Robot1", f"Robot{robot}") for f in MRCLAM_FILES]
            parts = [_head(_open(folder / f)) if (folder / f).exists() else b"" for f in files]
            add("mrclam", f"{folder.name}_robot{robot}.bin", SEPARATOR.join(parts))
    return count


if __name__ == "__main__":
    if sys.argv[1:2] == ["committed"]:
        committed()
    elif sys.argv[1:2] == ["shared"] and len(sys.argv) == 3:
        root = pathlib.Path(os.environ.get("PROBSLAM_SHARED_DATA", "/work/shared/data"))
        print(shared(pathlib.Path(sys.argv[2]), root))
    else:
        sys.exit(__doc__)
