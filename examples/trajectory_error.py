# Score a trajectory against a ground truth as evo does (ATE / RPE): EKF SLAM on the bundled MRCLAM
# excerpt against the robot's Vicon poses, both written as TUM files that evo reads too.
import probslam as ps

data = ps.datasets.load_landmark_dataset(ps.data.path("mrclam7_robot1_120s"))
run = ps.run_landmark_slam(data, "ekf", progress=False)     # times (T,) s, poses (T, 3)
truth = data.groundtruth                                     # rows t, x, y, theta (Vicon)
ps.io.write_trajectory(run.times, run.poses, "ekf.tum")      # t x y z qx qy qz qw
ps.io.write_trajectory(truth[:, 0], truth[:, 1:4], "vicon.tum")
est, ref = ps.io.read_trajectory("ekf.tum"), ps.io.read_trajectory("vicon.tum")
ate = ps.eval.ate(est.timestamps, est.poses, ref.timestamps, ref.poses)   # aligned (SE(2) Umeyama)
rpe = ps.eval.rpe(est.timestamps, est.poses, ref.timestamps, ref.poses, delta=1, delta_unit="m")
print(ate)                                                   # evo_ape's table: max mean median ...
print(f"RPE over 1 m: rmse {rpe.rmse:.3f} m over {rpe.count} pairs")
