# SLAM from a raw CARMEN log (odometry and scans): scan matching into submaps, GraphSLAM over them.
import probslam as ps

log = ps.data.path("intel_raw_loop.log.gz")  # or e.g. "aces.clf.bz2" (datasets: docs/cli.md)
result = ps.run_slam(log, progress=False)    # a path, a CarmenLog or LaserScans
result.poses, result.grid, result.graph      # (S, 3) laser poses, OccupancyGrid2D, PoseGraph2D
print(f"{len(result.poses)} scans, {result.graph.num_vertices} submaps, "
      f"map {result.grid.width} x {result.grid.height} cells")
# With a log that has a relations file (ACES: aces.relations, stamped with the log's ipc time), its accuracy:
# print(ps.eval.relations_error(result.timestamps, result.poses,
#                               ps.eval.relations_on_logger_time("aces.relations", ps.io.read_carmen_log(log).scans)))
