# The whole run of `probslam fastslam --unknown --particles 30 --seed 1 --refine graphslam` on the
# bundled MRCLAM excerpt, from Python: read, filter, refine, score, write (docs/python.md).
import probslam as ps
from probslam.pipelines import LandmarkRunOptions, run_landmark_dataset

options = LandmarkRunOptions(method="fastslam", unknown=True, fastslam=dict(num_particles=30, seed=1), refine="graphslam")
run = run_landmark_dataset(ps.data.path("mrclam7_robot1_120s"), options)
print(run.summary())                        # the lines `probslam fastslam --unknown ...` prints
run.write("fastslam")                       # fastslam_trajectory.tum; run.draw(pyplot) the picture
