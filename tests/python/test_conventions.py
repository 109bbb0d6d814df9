"""One convention across the package: a missing file raises FileNotFoundError naming it; writers
take the object first and the path second (the old write_g2o(path, graph) order still works,
with a DeprecationWarning)."""

import warnings

import numpy as np
import pytest

import probslam as ps
from probslam import graph as pg
from test_pose_graph import two_pose_graph


@pytest.mark.parametrize("writer", [pg.write_g2o, pg.write_isam, ps.write_g2o])
def test_writers_take_the_object_first(tmp_path, writer):
    path = tmp_path / "g.txt"
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        writer(two_pose_graph(), path)  # an os.PathLike is fine too
    back = ps.read_pose_graph(str(path), format="isam" if writer is pg.write_isam else "g2o")
    assert back.num_vertices == 2


@pytest.mark.parametrize("writer", [pg.write_g2o, pg.write_isam])
def test_the_old_order_warns_and_writes_the_same_file(tmp_path, writer):
    g = two_pose_graph()
    writer(g, str(tmp_path / "new.txt"))
    with pytest.warns(DeprecationWarning, match=rf"{writer.__name__}\(path, graph\) is deprecated"):
        writer(str(tmp_path / "old.txt"), g)
    assert (tmp_path / "old.txt").read_text() == (tmp_path / "new.txt").read_text()


def test_writer_arguments_are_checked_by_name(tmp_path):
    with pytest.raises(TypeError, match="graph: expected a PoseGraph2D"):
        pg.write_g2o("a.g2o", "b.g2o")
    with pytest.raises(TypeError, match="path: expected a str"):
        pg.write_g2o(two_pose_graph(), 3)


def test_missing_pose_graph_and_bt_raise_file_not_found(tmp_path):
    for call in (ps.read_pose_graph, ps.OccupancyGrid3D.read_bt, ps.io.load_ros_map, ps.OccupancyGrid2D.load,
                 ps.io.read_carmen_log, ps.io.read_victoria_park):
        with pytest.raises(FileNotFoundError, match="nothing.here"):
            call(tmp_path / "nothing.here")
    with pytest.raises(FileNotFoundError, match="Barcodes.dat"):
        ps.io.read_mrclam(tmp_path)


@pytest.mark.slow
def test_mrclam_reads_compressed_data_files(tmp_path, shared_data):
    import gzip
    import shutil

    src = shared_data / "landmark_slam/mrclam_dataset7"
    for name in ("Barcodes.dat", "Landmark_Groundtruth.dat", "Robot2_Measurement.dat"):
        shutil.copy(src / name, tmp_path / name)
    for name in ("Robot2_Odometry.dat", "Robot2_Groundtruth.dat"):
        (tmp_path / (name + ".gz")).write_bytes(gzip.compress((src / name).read_bytes()))
    packed, plain = ps.io.read_mrclam(tmp_path, robot=2), ps.io.read_mrclam(src, robot=2)
    np.testing.assert_array_equal(packed.odometry, plain.odometry)
    np.testing.assert_array_equal(packed.groundtruth, plain.groundtruth)
    np.testing.assert_array_equal(packed.measurements, plain.measurements)
