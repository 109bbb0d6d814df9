"""Small excerpts of public datasets shipped inside the package, so that every ``probslam``
command and every example runs right after installation (sources and licences: README.md in
this folder).

    >>> import probslam
    >>> probslam.data.path("intel_400.g2o")          # doctest: +SKIP
    '/.../probslam/data/intel_400.g2o'
"""

from __future__ import annotations

from importlib import resources
from typing import Dict

#: Every bundled file (or folder), with what it holds and which command uses it by default.
FILES: Dict[str, str] = {
    "intel_excerpt.log.gz": "CARMEN log, 180 scans of the Intel Research Lab with corrected poses (probslam map)",
    "intel_raw_loop.log.gz": "CARMEN log, 630 raw scans with odometry, the Intel Research Lab's first loop, "
                             "short of its start (probslam localize)",
    "intel_raw_lap.log.gz": "CARMEN log, 667 raw scans with odometry, the Intel Research Lab's first lap, back "
                            "past its start: a loop to close (probslam slam)",
    "intel_400.g2o": "g2o 2-D pose graph, the first 400 poses of the Intel Research Lab graph: 513 edges, "
                     "114 of them loop closures (probslam optimize)",
    "parking_garage_400.g2o": "g2o 3-D pose graph, the first 400 poses of the parking-garage graph: 500 edges, "
                              "101 of them loop closures, over three levels (probslam optimize FILE)",
    "victoria_park_1000.txt": "Victoria Park in iSAM's text format, the first 1000 poses (probslam ekf-slam / "
                              "fastslam with a file; read_pose_graph)",
    "mrclam7_robot1_120s": "UTIAS MRCLAM Dataset 7 folder, robot 1's first 120 s with Vicon ground truth "
                           "(probslam ekf-slam / fastslam by default)",
    "intel_raw_loop_map.yaml": "map_server map (0.1 m, with intel_raw_loop_map.pgm) of the bundled raw Intel loop, "
                               "made by probslam slam (probslam localize by default)",
    "intel_raw_loop_map.pgm": "the image of intel_raw_loop_map.yaml",
    "intel_laser_inverse.npz": "learned inverse sensor model (ch. 9.3) of the Intel Research Lab's laser, trained "
                               "on the first half of its corrected log (probslam map --inverse-model bundled)",
}


def path(name: str) -> str:
    """The absolute path of the bundled file or folder ``name`` (one of ``FILES``).

    Raises ValueError naming the files there are for an unknown name."""
    if name not in FILES:
        raise ValueError(f"name: no bundled data called {name!r}; there are: {', '.join(sorted(FILES))}")
    return str(resources.files(__name__) / name)


__all__ = ["FILES", "path"]
