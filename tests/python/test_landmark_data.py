"""Landmark dataset readers and EKF SLAM on real data (skipped without ../shared/data)."""

import dataclasses

import numpy as np
import pytest

import probslam as ps
from probslam import eval as ev
from probslam.datasets import mrclam, victoria_park

# Noise measured on MRCLAM Dataset 7 against its Vicon ground truth (see README): odometry
# sigma_v 0.11 m/s, sigma_w 0.43 rad/s per 10 ms command, inflated ~1.4x for its turn-rate
# bias; sensor sigma_phi 0.018 rad, mostly an offset shared by one scan's sightings, and sigma_r
# 0.10 m for the raw depth readings (0.02 m as distances), inflated: correlated errors the EKF
# does not model. The hidden-barcode runs need the room (README).
MRCLAM_MOTION = np.diag([0.15 ** 2, 0.6 ** 2])
MRCLAM_SENSOR = np.diag([0.15 ** 2, 0.04 ** 2])


@pytest.mark.slow
def test_mrclam_reader(tmp_path, shared_data):
    d = ps.io.read_mrclam(shared_data / "landmark_slam/mrclam_dataset7")
    assert d.odometry.shape == (58598, 3) and d.groundtruth.shape == (58389, 4)
    assert d.measurements.shape == (2578, 4) and d.robot_measurements == 650  # README counts
    assert set(np.unique(d.measurements[:, 1]).astype(int)) == set(range(6, 21))
    d1 = ps.io.read_mrclam(shared_data / "landmark_slam/mrclam_dataset1")
    assert d1.groundtruth is None and len(d1.measurements) == 4771


def test_mrclam_reader_errors(tmp_path):
    (tmp_path / "Barcodes.dat").write_text("# h\n6 63\n")
    (tmp_path / "Robot1_Odometry.dat").write_text("# h\n1.0 0.1 0.0\n2.0 0.1\n")
    with pytest.raises(ValueError, match=r"Robot1_Odometry\.dat:3"):
        ps.io.read_mrclam(tmp_path)
    (tmp_path / "Robot1_Odometry.dat").write_text("1.0 0.1 0.0\n")
    (tmp_path / "Robot1_Measurement.dat").write_text("1.0 99 1.0 0.1\n")
    (tmp_path / "Landmark_Groundtruth.dat").write_text("6 0 0 0 0\n")
    # Issue 12: a stray barcode is skipped and counted, not a reason to refuse the robot.
    stray = ps.io.read_mrclam(tmp_path)
    assert len(stray.measurements) == 0
    assert stray.skipped_rows == {"Robot1_Measurement.dat: barcode not in Barcodes.dat": 1}
    with pytest.raises(FileNotFoundError):
        ps.io.read_mrclam(tmp_path / "missing")


@pytest.mark.slow
def test_victoria_park_files_agree(shared_data):
    isam = ps.io.read_victoria_park(shared_data / "landmark_slam/victoria_park/victoriaPark.txt")
    gtsam = ps.io.read_victoria_park(shared_data / "landmark_slam/victoria_park/victoria_park_gtsam.txt")
    assert len(isam.delta) == 6968 and len(isam.xy) == 3640 and len(np.unique(isam.landmark)) == 151
    np.testing.assert_array_equal(isam.delta, gtsam.delta)
    # square-root information (iSAM) and covariance (GTSAM) describe the same noise
    np.testing.assert_allclose(isam.delta_cov, gtsam.delta_cov, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(isam.xy_cov, gtsam.xy_cov, rtol=1e-6)


def _victoria_park_reference(path, noise):
    """The line format read directly, as the Python reader before the C++ one (issue 34) did for
    well-formed files: ODOMETRY i j dx dy dth + 6 and LANDMARK i l dx dy + 3 upper-triangle
    entries, square-root information R (covariance (R^T R)^-1) or a covariance."""
    odometry, sightings = [], []
    for line in open(path):
        f = line.split()
        if not f or f[0].startswith("#"):
            continue
        n = 3 if f[0] == "ODOMETRY" else 2
        values = [float(x) for x in f[1:]]
        upper = np.zeros((n, n))
        upper[np.triu_indices(n)] = values[2 + n:]
        cov = upper + np.triu(upper, 1).T if noise == "covariance" else np.linalg.inv(upper.T @ upper)
        (odometry if n == 3 else sightings).append((values[:2 + n], cov))
    return odometry, sightings


# The previous Python reader's arrays (recorded 2026-11-26 at 599bf33 before it was replaced):
# (len(delta), len(xy), delta_cov.sum(), xy_cov.sum(), landmark.sum())
OLD_READER = {
    "victoriaPark.txt": (6968, 3640, 0.7525440000000001, 2911.999374128633, 4639589),
    "victoria_park_gtsam.txt": (6968, 3640, 0.7525440000000001, 2912.0000000000005, 4639589),
    "victoria_park_1000.txt": (999, 613, 0.10789200000000002, 490.3998945991352, 171333),
}


def _check_against_reference(path, noise):
    data = ps.io.read_victoria_park(path)
    odometry, sightings = _victoria_park_reference(path, noise)
    ids = np.array([v[:2] for v, _ in odometry])
    np.testing.assert_array_equal(data.pose_from, ids[:, 0])
    np.testing.assert_array_equal(data.pose_to, ids[:, 1])
    np.testing.assert_array_equal(data.delta, [v[2:5] for v, _ in odometry])
    np.testing.assert_allclose(data.delta_cov, [c for _, c in odometry], rtol=1e-12, atol=0)
    ids = np.array([v[:2] for v, _ in sightings])
    np.testing.assert_array_equal(data.pose, ids[:, 0])
    np.testing.assert_array_equal(data.landmark, ids[:, 1])
    np.testing.assert_array_equal(data.xy, [v[2:4] for v, _ in sightings])
    np.testing.assert_allclose(data.xy_cov, [c for _, c in sightings], rtol=1e-12, atol=0)
    assert data.skipped_rows == 0
    assert all(a.dtype == np.int64 for a in (data.pose_from, data.pose_to, data.pose, data.landmark))
    n_odo, n_obs, delta_cov_sum, xy_cov_sum, landmark_sum = OLD_READER[path.name]
    assert (len(data.delta), len(data.xy), int(data.landmark.sum())) == (n_odo, n_obs, landmark_sum)
    assert data.delta_cov.sum() == pytest.approx(delta_cov_sum, rel=1e-12)
    assert data.xy_cov.sum() == pytest.approx(xy_cov_sum, rel=1e-12)
    np.testing.assert_array_equal(data.delta_cov, np.swapaxes(data.delta_cov, 1, 2))
    np.testing.assert_array_equal(data.xy_cov, np.swapaxes(data.xy_cov, 1, 2))


def test_bundled_victoria_park_equals_the_line_format():
    import pathlib
    _check_against_reference(pathlib.Path(ps.data.path("victoria_park_1000.txt")), "sqrt_information")


@pytest.mark.slow
@pytest.mark.parametrize("name, noise", [("victoriaPark.txt", "sqrt_information"),
                                         ("victoria_park_gtsam.txt", "covariance")])
def test_shared_victoria_park_equals_the_line_format(shared_data, name, noise):
    _check_against_reference(shared_data / "landmark_slam/victoria_park" / name, noise)


def test_victoria_park_noise_is_explicit(tmp_path):
    # the same text as square-root information and as covariance (R = 2 I: covariance I / 4)
    (tmp_path / "vp.txt").write_text("ODOMETRY 0 1 1 0 0 2 0 0 2 0 2\nLANDMARK 1 7 2 1 2 0 2\n")
    (tmp_path / "vp_gtsam.txt").write_text((tmp_path / "vp.txt").read_text())
    root = ps.io.read_victoria_park(tmp_path / "vp.txt")
    np.testing.assert_allclose(root.delta_cov[0], np.eye(3) / 4, rtol=1e-15)
    np.testing.assert_allclose(root.xy_cov[0], np.eye(2) / 4, rtol=1e-15)
    for data in (ps.io.read_victoria_park(tmp_path / "vp_gtsam.txt"),  # auto: 'gtsam' in the name
                 ps.io.read_victoria_park(tmp_path / "vp.txt", noise="covariance")):
        np.testing.assert_allclose(data.delta_cov[0], 2 * np.eye(3), rtol=1e-15)
        np.testing.assert_allclose(data.xy_cov[0], 2 * np.eye(2), rtol=1e-15)


def test_victoria_park_reader_errors(tmp_path):
    bad = tmp_path / "vp.txt"
    bad.write_text("ODOMETRY 0 1 0.1 0 0 100 0 0 500 0 500\nLANDMARK 1 5 2.0 x 1 0 1\n")
    with pytest.raises(ValueError, match=r"vp\.txt:2"):
        ps.io.read_victoria_park(bad)
    bad.write_text("ODOMETRY 0 1 0.1 0 0 100\n")
    with pytest.raises(ValueError, match=r"vp\.txt:1.*12 fields"):
        ps.io.read_victoria_park(bad)
    with pytest.raises(ValueError, match="noise"):
        ps.io.read_victoria_park(bad, noise="information")


@pytest.mark.slow
def test_ekf_on_mrclam_known_correspondences_beats_reference(shared_data):
    d = ps.io.read_mrclam(shared_data / "landmark_slam/mrclam_dataset7")
    run = mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR)
    score = ev.score_mrclam(run, d)
    assert len(run.landmarks) == 15
    assert run.rejected / len(d.measurements) < 0.036  # the gate only takes gross outliers
    # a careful numpy EKF of Table 10.1 reaches about 0.30 m and 0.26 m on this data
    assert score.path_rmse_aligned < 0.30
    assert score.landmark_rmse_aligned < 0.26
    dr = ev.score_mrclam(mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, dead_reckoning=True), d)
    assert dr.path_rmse_aligned > 5 * score.path_rmse_aligned
    # distances instead of depth readings: the map (0.19 -> 0.07 m aligned) and the global
    # rotation (2.9 -> 0.9 m raw) both shrink; the aligned path stays within the reference
    fixed = ev.score_mrclam(mrclam.run_ekf(d.with_euclidean_ranges(), MRCLAM_MOTION, MRCLAM_SENSOR), d)
    assert fixed.path_rmse_aligned < 0.30
    assert fixed.landmark_rmse_aligned < score.landmark_rmse_aligned / 2
    assert fixed.landmark_rmse < score.landmark_rmse / 2



def synthetic_mrclam(survey_swap=()):
    """Five landmarks seen together from three poses, exact readings; the survey optionally
    with the positions of a pair exchanged (the labelling error of MRCLAM Dataset 1)."""
    landmarks = np.array([[6, 2.0, 0.0], [7, 0.0, 3.0], [8, -4.0, -1.0], [9, 5.0, 5.5], [10, 1.0, -6.0]])
    rows = []
    for t, (x, y, th) in enumerate([(0.0, 0.0, 0.1), (0.5, -0.5, 1.0), (1.0, 1.0, -2.0)]):
        for s, lx, ly in landmarks:
            rows.append([t, s, np.hypot(lx - x, ly - y), np.arctan2(ly - y, lx - x) - th])
    d = ps.io.Mrclam(np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]), np.array(rows), None, landmarks, 0)
    return d.with_survey_swapped(survey_swap)


def test_survey_label_swaps_finds_exchanged_positions():
    assert mrclam.survey_label_swaps(synthetic_mrclam()) == []
    swapped = synthetic_mrclam([(7, 9)])
    assert mrclam.survey_label_swaps(swapped) == [(7, 9)]
    np.testing.assert_array_equal(swapped.landmark_positions[7], [5.0, 5.5])
    residuals = mrclam.same_scan_residuals(synthetic_mrclam())
    assert all(np.allclose(r, 0.0, atol=1e-12) for r in residuals.values())
    with pytest.raises(ValueError, match="pairs"):
        synthetic_mrclam([(7, 42)])


def depth_mrclam(scale):
    """Landmarks ahead of three poses, read as MRCLAM's camera does: depth along the axis divided
    by ``scale`` (the distance is scale * reading / cos(bearing)); ground truth included."""
    landmarks = np.array([[6, 4.0, 0.5], [7, 5.0, 3.0], [8, 3.0, -2.0], [9, 6.5, -1.0]])
    poses = [(0.0, 0.0, 0.0, 0.1), (1.0, 0.5, -0.5, -0.2), (2.0, 1.0, 0.5, 0.3)]
    rows = []
    for t, x, y, th in poses:
        for s, lx, ly in landmarks:
            bearing = np.arctan2(ly - y, lx - x) - th
            rows.append([t, s, np.hypot(lx - x, ly - y) * np.cos(bearing) / scale, bearing])
    odometry = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    return ps.io.Mrclam(odometry, np.array(rows), np.array(poses), landmarks, 0)


def test_euclidean_ranges_from_depth_readings():
    d = depth_mrclam(0.97)
    assert mrclam.fit_range_scale(d) == pytest.approx(0.97, rel=1e-12)
    fixed = d.with_euclidean_ranges(0.97)
    np.testing.assert_array_equal(fixed.measurements[:, [0, 1, 3]], d.measurements[:, [0, 1, 3]])
    # distances now: the pose-free same-scan check closes exactly, and did not before
    assert all(np.allclose(r, 0.0, atol=1e-12) for r in mrclam.same_scan_residuals(fixed).values())
    assert max(np.abs(r).max() for r in mrclam.same_scan_residuals(d).values()) > 0.1
    assert d.measurements[0, 2] != fixed.measurements[0, 2]  # the original is left alone
    for bad in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(ValueError, match="scale"):
            d.with_euclidean_ranges(bad)
    behind = d.measurements.copy()
    behind[0, 3] = 2.0
    with pytest.raises(ValueError, match="measurements"):
        dataclasses.replace(d, measurements=behind).with_euclidean_ranges()
    with pytest.raises(ValueError, match="data"):
        mrclam.fit_range_scale(dataclasses.replace(d, groundtruth=None))
    with pytest.raises(ValueError, match="data"):
        mrclam.fit_range_scale(dataclasses.replace(d, measurements=np.empty((0, 4))))
    assert len(dataclasses.replace(d, measurements=np.empty((0, 4))).with_euclidean_ranges().measurements) == 0


def range_errors(data):
    """Reading minus the distance from the Vicon pose to the surveyed landmark, and the bearings."""
    m = data.measurements
    truth = np.array([data.landmark_positions[int(s)] for s in m[:, 1]])
    return m[:, 2] - np.hypot(*(truth - ev.truth_positions(data.groundtruth, m[:, 0])).T), m[:, 3]


def robust_std(e):
    return 1.4826 * np.median(np.abs(e - np.median(e)))


@pytest.mark.slow
def test_mrclam_ranges_are_camera_depths(shared_data):
    """MRCLAM's ranges are depths: against Vicon, the raw reading is short at the image edges and
    long at its centre; scale * range / cos(bearing) removes that and two thirds of the error.
    Dataset 1 (no Vicon) confirms the same constant pose-free, by the same-scan distances."""
    d7 = mrclam_dataset(shared_data, 7)
    assert mrclam.fit_range_scale(d7) == pytest.approx(ps.io.MRCLAM_RANGE_SCALE, abs=0.002)
    raw, bearing = range_errors(d7)
    fixed, _ = range_errors(d7.with_euclidean_ranges())
    edge, centre = np.abs(bearing) > 0.4, np.abs(bearing) < 0.1
    assert np.median(raw[edge]) < -0.15 and np.median(raw[centre]) > 0.05
    assert abs(np.median(fixed[edge])) < 0.02 and abs(np.median(fixed[centre])) < 0.02
    assert robust_std(fixed) < robust_std(raw) / 2.5
    d1 = mrclam_dataset(shared_data, 1).with_survey_swapped([(11, 17)])

    def same_scan_error(data):
        return np.median(np.abs(np.concatenate(list(mrclam.same_scan_residuals(data).values()))))

    assert same_scan_error(d1.with_euclidean_ranges()) < same_scan_error(d1) / 2.5


@pytest.mark.slow
def test_mrclam_cameras_differ_in_range_scale(shared_data):
    """MRCLAM_RANGE_SCALE is robot 1's: each Dataset 7 robot's camera has its own scale against
    Vicon, and robots 2 and 4's converted ranges read 6-8 cm long, enough to put sightings nearer
    a neighbour 0.18 m away in the survey (docs/ekf_slam.md's per-robot ceiling)."""
    mrclam_dataset(shared_data, 7)  # skips when absent
    folder = shared_data / "landmark_slam/mrclam_dataset7"
    scale, bias = {}, {}
    for robot in range(1, 6):
        d = ps.io.read_mrclam(folder, robot=robot)
        scale[robot] = mrclam.fit_range_scale(d)
        bias[robot] = float(np.median(range_errors(d.with_euclidean_ranges())[0]))
        own, _ = range_errors(d.with_euclidean_ranges(scale[robot]))
        assert abs(np.median(own)) < 0.01  # its own scale removes the constant error
    assert abs(bias[1]) < 0.01 and bias[2] > 0.06 and bias[4] > 0.05
    assert max(scale.values()) - min(scale.values()) > 0.02


def test_score_landmarks_aligns_the_map_onto_the_survey():
    d = synthetic_mrclam()
    c, s = np.cos(0.7), np.sin(0.7)
    # the survey seen from a frame rotated by 0.7 rad and shifted: aligned error zero
    moved = {int(i): np.array([[c, -s], [s, c]]) @ xy + [3.0, -1.0] for i, xy in d.landmark_positions.items()}
    score = ev.score_landmarks(moved, d)
    assert score.rmse > 1.0 and score.rmse_aligned < 1e-12
    moved[6] = moved[6] + 0.4  # one landmark off: it carries most of the error
    score = ev.score_landmarks(moved, d)
    assert max(score.errors, key=score.errors.get) == 6
    with pytest.raises(ValueError, match="landmarks"):
        ev.score_landmarks({6: np.zeros(2)}, d)


def test_survey_in_map_frame_inverts_the_alignment():
    """The survey drawn over a Dataset 1 map: each surveyed landmark moved by the inverse of the
    alignment lies on its map landmark when the map is exact, and in general as far from it as
    the aligned error says (a rigid motion keeps distances)."""
    d = synthetic_mrclam()
    c, s = np.cos(-1.2), np.sin(-1.2)
    moved = {int(i): np.array([[c, -s], [s, c]]) @ xy + [-2.0, 5.0] for i, xy in d.landmark_positions.items()}
    survey = ev.score_landmarks(moved, d).survey_in_map_frame(d)
    assert set(survey) == set(d.landmark_positions)
    for i, xy in moved.items():
        np.testing.assert_allclose(survey[i], xy, atol=1e-12)
    moved[6] = moved[6] + [0.3, -0.1]
    score = ev.score_landmarks(moved, d)
    survey = score.survey_in_map_frame(d)
    for i, error in score.errors.items():
        assert np.hypot(*(survey[i] - moved[i])) == pytest.approx(error, abs=1e-12)
    with pytest.raises(TypeError, match="^data: expected Mrclam"):
        score.survey_in_map_frame(None)


def mrclam_dataset(shared_data, number):
    folder = shared_data / f"landmark_slam/mrclam_dataset{number}"
    if not folder.is_dir():
        pytest.skip(f"{folder} not present")
    return ps.io.read_mrclam(folder)


#: Dataset 1 with known correspondences: the aligned map error reached once the survey labels are
#: fixed is 0.080 m (every landmark within 0.17 m); the bounds leave room for noise-model changes.
DATASET1_MAP_RMSE = 0.12  # m
DATASET1_LANDMARK_ERROR = 0.3  # m
#: The same with distances instead of MRCLAM's depth readings (``with_euclidean_ranges``): 0.029 m.
DATASET1_MAP_RMSE_DISTANCES = 0.05  # m


@pytest.mark.slow
def test_mrclam_dataset1_survey_labels_and_known_correspondences(shared_data):
    """Dataset 1 has no robot ground truth; its map is scored against the survey. The survey's
    subjects 11 and 17 carry each other's positions (the readings of one scan contradict their
    surveyed distances by metres, pose-free evidence), which once looked like a 2.2 m divergence."""
    d = mrclam_dataset(shared_data, 1)
    assert mrclam.survey_label_swaps(d) == [(11, 17)]
    assert mrclam.survey_label_swaps(mrclam_dataset(shared_data, 7)) == []
    run = mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR)
    assert len(run.landmarks) == 15 and run.rejected / len(d.measurements) < 0.036
    as_labelled = ev.score_landmarks(run.landmarks, d)
    assert as_labelled.errors[11] > 5 and as_labelled.errors[17] > 5  # each at the other's place
    score = ev.score_landmarks(run.landmarks, d.with_survey_swapped([(11, 17)]))
    assert score.rmse_aligned < DATASET1_MAP_RMSE
    assert max(score.errors.values()) < DATASET1_LANDMARK_ERROR
    # innovations: the used NIS average below 2 (2 dof), the noise being inflated on purpose
    used = run.innovations[(run.innovations[:, 3] > 0) & np.isfinite(run.innovations[:, 2])]
    assert len(used) == len(d.measurements) - run.rejected - 15 and used[:, 2].mean() < 2.0
    dead = ev.score_landmarks(mrclam.dead_reckoning_map(d), d.with_survey_swapped([(11, 17)]))
    assert dead.rmse_aligned > 10 * score.rmse_aligned
    run = mrclam.run_ekf(d.with_euclidean_ranges(), MRCLAM_MOTION, MRCLAM_SENSOR)
    assert ev.score_landmarks(run.landmarks, d.with_survey_swapped([(11, 17)])).rmse_aligned < DATASET1_MAP_RMSE_DISTANCES


@pytest.mark.slow
def test_ekf_on_mrclam_unknown_correspondences(shared_data):
    """Barcodes hidden. The landmarks stand in clusters 0.18 m apart, about the error of one
    sighting: even placed from the Vicon pose, 13% of the sightings fall nearer another landmark
    than their own (15% with the raw depth readings), and fitting each scan's common bearing
    offset with the true pose and map still leaves 4.5% wrong, so the issue's 95% is beyond a
    filter here (studies/mrclam_association_ceiling.py). Joint compatibility over each scan
    does better than maximum likelihood and keeps the clusters apart (15 landmarks); these are
    the figures reached, kept from regressing."""
    raw = mrclam_dataset(shared_data, 7)
    accuracy, count = {}, {}
    for method in ("ml", "jcbb"):
        run = mrclam.run_ekf(raw.with_euclidean_ranges(), MRCLAM_MOTION, MRCLAM_SENSOR, known=False,
                                association=method)
        accuracy[method], count[method] = ev.association_accuracy(run), len(run.landmarks)
        assert run.associations.applied > 0.97 * len(raw.measurements)  # almost nothing is discarded
    assert accuracy["jcbb"] >= 0.85 and abs(count["jcbb"] - 15) <= 1
    assert accuracy["jcbb"] > accuracy["ml"] + 0.03
    assert abs(count["ml"] - 15) <= 1  # no cluster collapse: a landmark explains one sighting per scan
    run = mrclam.run_ekf(raw, MRCLAM_MOTION, MRCLAM_SENSOR, known=False)  # depth readings: worse
    assert ev.association_accuracy(run) < accuracy["jcbb"] - 0.05


@pytest.mark.slow
def test_mrclam_dataset1_unknown_correspondences_multiple_hypotheses(shared_data):
    """Dataset 1, barcodes hidden: the issue's 95% correct with 15 +- 1 landmarks. Its landmarks
    stand 1-10 m apart, but the robot goes up to 37 s without one and comes back with its heading
    0.2-0.3 rad uncertain; one filter then pairs a lone sighting with the wrong landmark and the
    errors cascade (JCBB: 81-85% correct, 40-49 landmarks). A beam of ten filters keeps the other
    branch until later scans decide. With the raw depth readings it still splits landmarks seen
    at the image edge, where the reading is 0.3 m short (97.8%, 21 landmarks); with distances,
    99.96% and 15, mapped to 0.031 m after alignment."""
    raw = mrclam_dataset(shared_data, 1)
    d = raw.with_euclidean_ranges()
    survey = d.with_survey_swapped([(11, 17)])
    single = mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="jcbb")
    run = mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="mht")
    assert run.associations.applied > 0.99 * len(d.measurements)  # under 1% dropped as clutter
    assert ev.association_accuracy(run) >= 0.99 and ev.association_accuracy(single) < 0.95
    assert abs(len(run.landmarks) - 15) <= 1 < len(single.landmarks) - 15
    labels = ev.majority_labels(run)
    assert sorted(labels[i] for i in run.landmarks) == list(range(6, 21))  # one landmark per barcode
    score = ev.score_landmarks(run.landmarks, survey, labels)
    assert score.rmse_aligned < DATASET1_MAP_RMSE_DISTANCES
    # raw readings: duplicates, but each barcode's landmark with the most sightings maps well
    split = mrclam.run_ekf(raw, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="mht")
    assert len(split.landmarks) > 16 and ev.association_accuracy(split) >= 0.95
    primary = ev.primary_landmarks(split)
    score = ev.score_landmarks({i: split.landmarks[i] for i in primary.values()}, survey,
                               {i: t for t, i in primary.items()})
    assert len(primary) == 15 and score.rmse_aligned < DATASET1_MAP_RMSE


@pytest.mark.slow
def test_ekf_on_victoria_park(shared_data):
    data = ps.io.read_victoria_park(shared_data / "landmark_slam/victoria_park/victoriaPark.txt")
    run = victoria_park.run_ekf(data)
    assert run.filter.num_landmarks == 151 and len(run.poses) == 6969
    cov = run.filter.covariance
    assert np.array_equal(cov, cov.T) and np.linalg.eigvalsh(cov).min() > 0
    # the car drives about 3.5 km around the park and comes back near its start
    steps = np.hypot(*np.diff(run.poses[:, :2], axis=0).T)
    assert steps.sum() > 3000


@pytest.mark.slow
def test_cli_ekf_slam(tmp_path, capsys, shared_data):
    from probslam import cli

    vp = shared_data / "landmark_slam/victoria_park/victoriaPark.txt"
    assert cli.main(["ekf-slam", str(vp), "-o", str(tmp_path / "vp")]) == 0
    out = capsys.readouterr().out
    assert "landmarks:     151" in out
    assert (tmp_path / "vp.png").read_bytes()[:4] == b"\x89PNG"
    assert ps.io.read_trajectory(tmp_path / "vp_trajectory.tum").poses.shape == (6969, 3)
    assert cli.main(["ekf-slam", str(tmp_path / "missing.txt"), "-o", str(tmp_path / "x")]) == 2


@pytest.mark.slow
def test_cli_ekf_slam_mrclam(tmp_path, capsys, shared_data):
    """MRCLAM through the CLI: distances by default, the logged depth readings on request."""
    from probslam import cli

    mrclam_dataset(shared_data, 1), mrclam_dataset(shared_data, 7)  # skips without them
    d1, d7 = (str(shared_data / f"landmark_slam/mrclam_dataset{n}") for n in (1, 7))
    assert cli.main(["ekf-slam", d1, "--unknown", "--association", "mht", "-o", str(tmp_path / "d1")]) == 0
    out = capsys.readouterr().out
    assert f"ranges from depth x {ps.io.MRCLAM_RANGE_SCALE}" in out and "landmarks:     15 in the map" in out
    assert "subjects 11<->17 exchanged" in out and (tmp_path / "d1.png").exists()
    assert cli.main(["ekf-slam", d7, "--raw-ranges", "-o", str(tmp_path / "d7")]) == 0
    out = capsys.readouterr().out
    assert "raw depth readings" in out and "12 gated as outliers" in out
    assert ps.io.read_trajectory(tmp_path / "d7_trajectory.tum").poses.shape == (58598, 3)


def test_before_scan_sees_each_scan_and_the_filter_before_it_takes_it():
    d = depth_mrclam(1.0)
    seen = []

    def hook(ekf, rows):
        seen.append((rows[0, 0], len(rows), ekf.num_landmarks))

    run = mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, before_scan=hook)
    # three scans of four landmarks, the first ahead of any landmark, the filter the run's own
    assert seen == [(0.0, 4, 0), (1.0, 4, 4), (2.0, 4, 4)] and run.filter.num_landmarks == 4
    mht_seen = []
    mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="mht",
                      before_scan=lambda f, rows: mht_seen.append(type(f).__name__))
    assert mht_seen == ["MultiHypothesisEkfSlam"] * 3


# --- issue 34: one front door (run_landmark_slam), one result type, the scores in eval ----------

def _bundled_mrclam():
    return ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"))


@pytest.mark.parametrize("method, known, driver", [
    ("ekf", True, lambda d: mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR)),
    ("ekf", False, lambda d: mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="jcbb")),
    ("mht", False, lambda d: mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False, association="mht")),
    ("fastslam", False, lambda d: mrclam.run_fastslam(d, MRCLAM_MOTION, MRCLAM_SENSOR, known=False,
                                                      num_particles=10)),
    ("dead-reckoning", True, lambda d: mrclam.run_ekf(d, MRCLAM_MOTION, MRCLAM_SENSOR, dead_reckoning=True)),
])
def test_run_landmark_slam_is_the_dataset_driver(method, known, driver):
    """The front door runs the dataset's driver with the dataset's defaults (MRCLAM's are the
    noise this file measured), and a path is read as load_landmark_dataset reads it."""
    data = _bundled_mrclam()
    options = dict(num_particles=10) if method == "fastslam" else {}
    run = ps.run_landmark_slam(data, method, known=known, **options)
    direct = driver(data)
    assert run.method == method == direct.method
    np.testing.assert_array_equal(run.poses, direct.poses)
    np.testing.assert_array_equal(run.times, direct.times)
    assert run.landmarks.keys() == direct.landmarks.keys()
    assert (run.associations is None) == known
    if not known:
        np.testing.assert_array_equal(run.associations.ids, direct.associations.ids)
        assert len(run.associations) == len(data.measurements)  # every sighting, in the order taken
    from_path = ps.run_landmark_slam(ps.data.path("mrclam7_robot1_120s"), method, known=known, **options)
    np.testing.assert_array_equal(from_path.poses, run.poses)
    with pytest.raises(dataclasses.FrozenInstanceError):
        run.poses = None


def test_dead_reckoning_follows_the_odometry():
    """The baseline method against dead_reckoning's own integration of the (t, v, w) rows: the
    run's pose after control k is dead reckoning's pose at the next stamp."""
    data = _bundled_mrclam()
    run = ps.run_landmark_slam(data, "dead-reckoning")
    reference = mrclam.dead_reckoning(data.odometry, mrclam.start_pose(data))
    np.testing.assert_allclose(run.poses[:-1, :2], reference[1:, :2], atol=1e-9)
    assert run.landmarks == {} and run.associations is None


def test_run_landmark_slam_refuses_what_it_cannot_run():
    data = _bundled_mrclam()
    park = ps.io.read_victoria_park(ps.data.path("victoria_park_1000.txt"))
    for call, exc, message in [
        (lambda: ps.run_landmark_slam(data, "graph"), ValueError, "^method must be one of"),
        (lambda: ps.run_landmark_slam(data, "mht"), ValueError, "^known: method 'mht'"),
        (lambda: ps.run_landmark_slam(data, known=False, association="mht"), ValueError, "^association"),
        (lambda: ps.run_landmark_slam(data, known=1), TypeError, "^known"),
        (lambda: ps.run_landmark_slam(data, hypotheses={}), ValueError, "^hypotheses"),
        (lambda: ps.run_landmark_slam(park, "mht", known=False), ValueError, "MRCLAM only"),
        (lambda: ps.run_landmark_slam(park, known=False), ValueError, "^known"),
        (lambda: ps.run_landmark_slam(park, motion_noise=MRCLAM_MOTION), ValueError, "^motion_noise"),
        (lambda: ps.run_landmark_slam(None), TypeError, "^dataset"),
    ]:
        with pytest.raises(exc, match=message):
            call()


def test_load_landmark_dataset_says_what_a_path_is(tmp_path):
    assert ps.datasets.landmark_dataset_kind(ps.data.path("mrclam7_robot1_120s")) == "mrclam"
    assert ps.datasets.landmark_dataset_kind(ps.data.path("victoria_park_1000.txt")) == "victoria_park"
    assert isinstance(_bundled_mrclam(), ps.io.Mrclam)
    assert isinstance(ps.datasets.load_landmark_dataset(ps.data.path("victoria_park_1000.txt")), ps.io.VictoriaPark)
    (tmp_path / "folder").mkdir()
    (tmp_path / "empty.txt").write_text("")
    (tmp_path / "odometry_only.txt").write_text("ODOMETRY 0 1 1 0 0 2 0 0 2 0 2\n")
    for path, exc, message in [(tmp_path / "folder", ValueError, "folder without Barcodes.dat"),
                               (tmp_path / "empty.txt", ValueError, "empty file"),
                               (tmp_path / "odometry_only.txt", ValueError, "no LANDMARK records"),
                               (tmp_path / "missing", FileNotFoundError, "no such file")]:
        with pytest.raises(exc, match=message):
            ps.datasets.load_landmark_dataset(path)
    short = ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"), seconds=30.0, raw_ranges=True)
    assert short.odometry[-1, 0] - short.odometry[0, 0] <= 30.0
    raw = ps.io.read_mrclam(ps.data.path("mrclam7_robot1_120s"))
    within = raw.measurements[raw.measurements[:, 0] <= short.odometry[0, 0] + 30]
    np.testing.assert_array_equal(short.measurements, within)


def _hand_run(truth, ids, landmarks):
    """A hidden-correspondence result built by hand: sightings (true label, filter id)."""
    record = ps.datasets.Associations(np.zeros(len(truth)), np.array(truth, np.int64), np.array(ids, np.int64))
    return ps.LandmarkSlamResult("ekf", np.zeros(1), np.zeros((1, 3)), {i: np.zeros(2) for i in landmarks}, None,
                                 associations=record)


def test_association_scores_by_hand():
    """Filter landmark 0 took labels 6, 6, 7; landmark 1 took 7, 7; landmark 2 took 8 and
    was later removed; one sighting was discarded (-1): 6 of the 6 applied sightings but one
    (the 7 on landmark 0) went to their majority label."""
    run = _hand_run([6, 6, 7, 7, 7, 8, 9], [0, 0, 0, 1, 1, 2, -1], landmarks=[0, 1])
    assert ev.majority_labels(run) == {0: 6, 1: 7, 2: 8}
    assert ev.association_accuracy(run) == pytest.approx(5 / 6)
    assert ev.primary_landmarks(run) == {6: 0, 7: 1}  # label 7: two sightings on 1, one on 0
    assert run.associations.applied == 6
    assert np.isnan(ev.association_accuracy(_hand_run([6], [-1], landmarks=[])))
    with pytest.raises(ValueError, match="^result: a run with known correspondences"):
        ev.association_accuracy(ps.run_landmark_slam(_bundled_mrclam()))
