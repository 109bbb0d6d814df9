# Options as one typed object: built once, copied, changed by name, handed to the filter.
import probslam as ps

options = ps.MonteCarloLocalizationOptions(max_particles=5000, seed=7)
options.beam.sigma_hit = 0.1                          # groups are attributes: beam, odometry
tuned = options.replace(sensor_model="beam", odometry={"alpha1": 0.05})  # a validated copy
print(tuned.odometry, tuned == options)              # OdometryMotionNoise(alpha1=0.05, ...) False
try:
    options.replace(beam={"z_hit": 0.9})               # the mixture's weights must sum to 1
except ValueError as error:
    print(error)                                      # beam.z_hit + z_short + ... must sum to 1 ...

grid = ps.io.load_ros_map(ps.data.path("intel_raw_loop_map.yaml"))
mcl = ps.MonteCarloLocalization(grid, options=tuned, max_particles=2000)  # a keyword replaces a field
print(mcl.options.max_particles, mcl.options.sensor_model)  # 2000 beam
