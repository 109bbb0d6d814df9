# The face every stateful class shares (docs/api.md): required arguments positionally, every
# option a keyword (the laser SLAM classes: one options object, options=, its fields also by
# keyword, a group as a dict or an object); the same names (pose, landmarks(), ...); named results.
import numpy as np
import probslam as ps

f = ps.FastSlam(np.diag([0.01, 0.01, 0.002]), np.diag([0.01, 0.001]), version=2, seed=3)  # model, options
slam = ps.SubmapSlam2D(frontend={"filter": {"max_range": 30.0}, "submap_distance": 10.0})  # options only
rbpf = ps.GridFastSlam(options=ps.GridFastSlamOptions(num_particles=30, proposal="scan-matching"))
print(slam.options.closures.min_match_quality, rbpf.options.update)    # what each runs with

f.predict(1.0, 0.1, 0.1)                              # v m/s, w rad/s, dt s
result = f.update([[4.0, 0.3], [6.0, -0.5]], [0, 1])  # a FastSlamUpdateResult
landmarks = f.landmarks()                             # the best particle's map: Landmarks
print(result, landmarks, landmarks.means.shape, f.pose, f.num_landmarks)
