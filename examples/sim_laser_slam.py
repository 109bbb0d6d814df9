# A simulated laser robot (probslam.sim_laser): a Stage-like laser (270 deg, 90 beams, 5 m) with
# good wheel odometry drives a loop through a seeded office; the log is written as CARMEN and as a
# ROS 2 bag with its exact ground truth as TUM, then mapped and scored against that truth.
import probslam as ps

sim = ps.sim_laser.simulate("office", "stage", "good", seed=0)   # also: "corridor", "hall", "repeated"
ps.sim_laser.write_carmen(sim, "office_stage.log")               # ROBOTLASER1 + ODOM
ps.sim_laser.write_bag(sim, "office_stage_bag", format="rosbag2")  # or "rosbag1", "mcap"
ps.sim_laser.write_truth(sim, "office_stage_truth.tum")
result = ps.slam.run_slam("office_stage.log", progress=False)
truth = ps.io.read_trajectory("office_stage_truth.tum")
ate = ps.eval.ate(result.timestamps, result.poses, truth.timestamps, truth.poses)
odometry = ps.eval.ate(sim.timestamps, sim.odometry, sim.timestamps, sim.truth)
print(f"{len(sim.truth)} scans: SLAM ATE {ate.rmse:.3f} m, odometry alone {odometry.rmse:.3f} m")
