"""A simulated corridor loop with noisy odometry and laser scans, shared by the laser SLAM tests
(SubmapSlam2D, GridFastSlam)."""

import numpy as np

import probslam as ps
from probslam.sim import cast_ranges

# A rectangular corridor loop (outer 20 x 12 m, inner block 3..17 x 3..9) with alcoves and
# pillars so that no stretch is a featureless corridor.
OUTER = [(0.02, 0.03), (20.01, 0.03), (20.01, 12.02), (0.02, 12.02)]
INNER = [(3.01, 3.02), (17.03, 3.02), (17.03, 9.01), (3.01, 9.01)]


def _boxes():
    boxes = []
    for cx, cy in [(5.5, 0.3), (9.2, 0.4), (14.1, 0.3), (19.7, 4.1), (19.6, 8.3), (15.2, 11.7), (10.3, 11.6),
                   (4.4, 11.7), (0.3, 7.7), (0.4, 3.9), (7.3, 3.3), (12.6, 8.7)]:
        h = 0.3 if (cx, cy) not in [(9.2, 0.4), (10.3, 11.6)] else 0.45
        boxes.append([(cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h)])
    return boxes


def _segments():
    segs = []
    for poly in [OUTER, INNER] + _boxes():
        for k in range(len(poly)):
            segs.append((np.asarray(poly[k]), np.asarray(poly[(k + 1) % len(poly)])))
    return segs


SEGMENTS = _segments()
ANGLES = np.linspace(-np.pi / 2, np.pi / 2, 181)
MAX_RANGE = 12.0


def cast(pose):
    """Ranges from `pose` to the nearest segment along each beam (MAX_RANGE where none)."""
    return np.minimum(cast_ranges(pose, ANGLES, SEGMENTS), MAX_RANGE)


def corridor_drive(laps=1.25, step=0.25, bias=0.0015, seed=5):
    """True poses along the corridor's centre line (counter-clockwise), odometry with a heading
    bias and noise, and noisy ranges."""
    rng = np.random.default_rng(seed)
    corners = np.array([(1.5, 1.5), (18.5, 1.5), (18.5, 10.5), (1.5, 10.5)])
    legs = [(corners[k], corners[(k + 1) % 4]) for k in range(4)]
    perimeter = sum(np.linalg.norm(b - a) for a, b in legs)
    poses = []
    for s in np.arange(0.0, laps * perimeter, step):
        s %= perimeter
        for a, b in legs:
            length = np.linalg.norm(b - a)
            if s <= length:
                p = a + (b - a) * s / length
                poses.append([p[0], p[1], np.arctan2(*(b - a)[::-1])])
                break
            s -= length
    true = np.array(poses)
    odo = [true[0].copy()]
    for k in range(1, len(true)):
        d = ps.Pose2(*true[k - 1]).between(ps.Pose2(*true[k]))
        inc = np.array([d.x, d.y, d.theta]) + rng.normal(0, [0.01, 0.005, 0.005]) + [0.0, 0.0, bias]
        odo.append(np.asarray(ps.Pose2(*odo[-1]).compose(ps.Pose2(*inc)).as_array()))
    ranges = np.stack([cast(p) for p in true]) + rng.normal(0, 0.01, (len(true), len(ANGLES)))
    return true, np.array(odo), ranges


def scans_of(true, odo, ranges):
    """The drive as the LaserScans a CARMEN log would give (one scan per second)."""
    from probslam.io.carmen import LaserScans

    s = len(true)
    return LaserScans(ranges=ranges, laser_poses=odo, robot_poses=odo, start_angles=np.full(s, ANGLES[0]),
                      angular_resolutions=np.full(s, ANGLES[1] - ANGLES[0]), max_ranges=np.full(s, MAX_RANGE),
                      num_beams=np.full(s, len(ANGLES)), timestamps=np.arange(s, dtype=float))
