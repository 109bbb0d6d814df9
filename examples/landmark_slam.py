# Landmark SLAM on a public dataset: a UTIAS MRCLAM robot (or a Victoria Park file), scored.
import probslam as ps

data = ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"), robot=1)  # or a folder / file
run = ps.run_landmark_slam(data, "fastslam", known=False, num_particles=30)  # or "ekf", "mht"
labels = ps.eval.majority_labels(run)       # filter landmark -> the barcode most of its sightings carry
score = ps.eval.score_mrclam(run, data, labels)
print(f"{len(run.landmarks)} landmarks, {ps.eval.association_accuracy(run):.1%} of the sightings right; "
      f"path RMSE {score.path_rmse_aligned:.3f} m after alignment")
