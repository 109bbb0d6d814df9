# A CARMEN log written as a ROS bag, then read back and mapped as a robot's bag would be (needs
# rosbags: pip install 'probslam[ros]').
import probslam as ps

raw = ps.io.read_carmen_log(ps.data.path("intel_raw_loop.log.gz"))
ps.io.write_rosbag(raw, "intel_raw.bag")       # format="rosbag2" or "mcap": a ROS 2 folder
log = ps.io.read_rosbag("intel_raw.bag")        # topics found by type; scan_topic=... to choose
print(log.describe())                           # topics, pose source, laser offset, skipped
result = ps.run_slam(log, progress=False)       # as for a CARMEN log
print(f"{len(result.poses)} scans, {result.graph.num_vertices} submaps")
