# Monte Carlo localization of the bundled raw Intel loop in the map probslam slam made of it.
import probslam as ps

grid = ps.io.load_ros_map(ps.data.path("intel_raw_loop_map.yaml"))  # or a PREFIX.yaml of probslam slam
log = ps.data.path("intel_raw_loop.log.gz")
result = ps.localize(log, grid, progress=False)  # global: no initial_pose; a pose (x, y, theta) tracks
result.poses, result.num_particles               # (S, 3) laser poses in the map's frame, (S,) KLD's count
print(f"{len(result.poses)} scans, converged after {result.convergence_time:.1f} s of log "
      f"({result.travel_to_converge:.1f} m), {result.real_time_factor:.0f}x real time, "
      f"{result.num_particles[-1]} particles at the end")
