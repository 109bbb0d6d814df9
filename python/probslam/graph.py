"""2-D pose/landmark graphs: reading, optimising (Gauss-Newton / Levenberg-Marquardt on CHOLMOD),
marginal covariances, writing. The math is in C++; this module only names things."""

from __future__ import annotations

from ._core import OptimizationReport, PoseGraph2D, marginal_covariances, optimize, read_pose_graph, write_g2o

__all__ = [
    "OptimizationReport",
    "PoseGraph2D",
    "marginal_covariances",
    "optimize",
    "read_pose_graph",
    "write_g2o",
]
