"""A pose graph file from disk to its optimum: read (2-D or 3-D, any format the readers know),
start (the file's values, odometry, chordal, EKF, incremental), optimise, then write the graph
and its trajectory and draw it. ``optimize_file(path, options)`` runs it all;
``GraphFileRun`` runs it step by step for a caller that reports each step (``probslam
optimize``). Options travel as one ``GraphFileOptions``; every refusal names its field.
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import dataclass, field, fields
from typing import Callable, List, Optional, Union

import numpy as np

from ._options import Options, described
from .inputs import ANY_POSE_GRAPH, reading
from .. import graph as pg
from .._args import positive_real
from .._progress import progress_bar
from .. import io
from ..io.landmark_datasets import isam_noise_convention

PathLike = Union[str, "os.PathLike[str]"]

#: Each dimension's start when none is named: the file's values in 2-D, the chordal relaxation of
#: the rotations in 3-D (Gauss-Newton from the values in a file such as torus3D's, or from dead
#: reckoning on noisier graphs, stalls in a wrong minimum).
DEFAULT_INIT = {2: "file", 3: "chordal"}
#: ...except for a 2-D graph with landmarks: the EKF SLAM estimate. A landmark's value in a file
#: (or placed from its first sighting on dead reckoning, as iSAM files are read) is off by the
#: drift up to that sighting, and Gauss-Newton from there stalls: on Victoria Park 100 iterations
#: to chi2 3.4e7, against 6184.12 in 5 from the EKF (docs/pose_graphs.md).
LANDMARK_GRAPH_INIT = "ekf"
LANDMARK_GRAPH_INIT_REASON = "the graph has landmarks: the EKF SLAM estimate places them"
INITIALIZATIONS = ("file", "odometry", "ekf", "incremental", "chordal")
INITS_2D_ONLY = ("ekf", "incremental")
INITS_3D_ONLY = ("chordal",)
ALGORITHMS = ("gauss-newton", "levenberg-marquardt")
KERNELS = ("none", "huber", "cauchy")
#: What a graph file's noise entries hold (``graph.read_pose_graph``'s ``noise``; auto: the format's own).
NOISE_CONVENTIONS = ("auto", "information", "sqrt_information", "covariance")
#: Records only iSAM text has: a file whose first record is one is iSAM whatever its name.
ISAM_ONLY_RECORDS = ("ODOMETRY", "LANDMARK")


@dataclass
class GraphFileOptions(Options):
    """How ``optimize_file`` reads, starts and optimises a graph file."""

    format: str = described("auto", "the graph file's format (auto: from its records and extension)",
                            choices=("auto", "g2o", "toro", "isam"))
    noise: str = described("auto", "what the edges' noise entries hold (auto: the format's own, covariances in "
                           "GTSAM's iSAM copies named '*gtsam*')", choices=NOISE_CONVENTIONS)
    init: Optional[str] = described(None, "the start (None: file in 2-D, chordal in 3-D, dead reckoning for iSAM "
                                    "files, ekf for 2-D graphs with landmarks: DEFAULT_INIT, LANDMARK_GRAPH_INIT)",
                                    choices=INITIALIZATIONS)
    poses_per_step: Optional[int] = described(None, "with ``init`` incremental: poses per step (None: 100)", type=int)
    algorithm: str = described("gauss-newton", "the least-squares solver", choices=ALGORITHMS)
    max_iterations: int = described(100, "iterations at most (the command exits with status 3 if they end the run)")
    kernel: str = described("none", "robust kernel", choices=KERNELS)
    kernel_width: Optional[float] = described(None, "with a ``kernel``: its width, in units of sqrt(chi2) (None: 1)",
                                              type=float)
    linear_solver: Optional[str] = described(None, "sparse Cholesky (None: supernodal)",
                                             choices=("simplicial", "supernodal", "auto"))
    ordering: Optional[str] = described(None, "fill-reducing ordering (None: amd in 2-D, metis in 3-D)",
                                        choices=("amd", "metis"))

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        for name, choices in (("noise", NOISE_CONVENTIONS), ("algorithm", ALGORITHMS), ("kernel", KERNELS)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{name} must be one of {', '.join(choices)}, got {getattr(self, name)!r}")
        if self.init is not None and self.init not in INITIALIZATIONS:
            raise ValueError(f"init must be one of {', '.join(INITIALIZATIONS)}, got {self.init!r}")
        for name, lowest in (("max_iterations", 0), ("poses_per_step", 1)):
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise TypeError(f"{name} must be an int")
            if not lowest <= value < 2 ** 31:
                raise ValueError(f"{name} must lie in [{lowest}, 2^31)")
        if self.kernel_width is not None:
            if self.kernel == "none":
                raise ValueError("kernel_width applies with kernel huber or cauchy only")
            positive_real(self.kernel_width, "kernel_width")
        if self.poses_per_step is not None and self.init != "incremental":
            raise ValueError("poses_per_step applies with init incremental only")


@dataclass
class GraphFileRun:
    """One graph file's run, step by step: ``read`` it, ``start`` it, ``optimize`` it, then
    ``write`` and ``draw``. Each step's figures are fields; ``*_summary`` say them in words."""

    path: str
    options: GraphFileOptions
    dimension: int
    graph: object
    read_report: object
    noise: str
    read_seconds: float
    init: str = "file"
    init_reason: str = ""
    init_seconds: float = 0.0
    initial_poses: Optional[np.ndarray] = None
    initial_chi2: float = math.nan
    chi2_history: List[float] = field(default_factory=list)
    report: object = None  # the OptimizationReport; None until optimized, or when interrupted
    interrupted: bool = False
    optimize_seconds: float = 0.0

    @classmethod
    def read(cls, path: PathLike, options: Optional[GraphFileOptions] = None) -> "GraphFileRun":
        """Reads the graph at ``path`` (2-D or 3-D by its records). ValueError for a file with no
        vertex, a start of the other dimension, or a bad row (naming its line); an InputError
        (``inputs.reading``) naming the file and what was expected when it is not a graph."""
        options = GraphFileOptions() if options is None else options
        if not isinstance(options, GraphFileOptions):
            raise TypeError(f"options: expected a GraphFileOptions, got {type(options).__name__}")
        options.validate()
        path = os.fspath(path)
        with reading(path, ANY_POSE_GRAPH, [f.name for f in fields(GraphFileOptions)]):  # errors name the file
            dimension = pg.pose_graph_dimension(path)
            init = options.init or DEFAULT_INIT[dimension]
            other_only = INITS_2D_ONLY if dimension == 3 else INITS_3D_ONLY
            if init in other_only:
                choices = ", ".join(i for i in INITIALIZATIONS if i not in other_only)
                raise ValueError(f"init {init} applies to {5 - dimension}-D graphs; {path} is a {dimension}-D graph "
                                 f"(its starting points: {choices})")
            noise = _noise_convention(path, options)
            t0 = time.perf_counter()
            read = (pg.read_pose_graph_3d_with_report if dimension == 3 else pg.read_pose_graph_with_report)(
                path, format=options.format, noise=noise, rows="strict")
            if read.graph.num_vertices == 0:
                raise ValueError(f"{path}: no vertices")
            run = cls(path, options, dimension, read.graph, read.report, noise, time.perf_counter() - t0, init=init)
            if options.init is None and dimension == 2 and len(run.graph.point_ids):
                run.init, run.init_reason = LANDMARK_GRAPH_INIT, LANDMARK_GRAPH_INIT_REASON
            return run

    def read_summary(self, name: Optional[str] = None) -> str:
        """What was read, in lines (``name``: how to call the file; default its path)."""
        g, r = self.graph, self.read_report
        name = self.path if name is None else name
        lines = []
        if self.noise != "default" and self.options.noise == "auto":
            lines.append(f"noise:      {self.noise} (an iSAM file named as GTSAM's copies: {os.path.basename(self.path)}; "
                         "--noise sets another)")
        if self.dimension == 3:
            points = f"{g.num_points} points, {g.num_point_edges} point edges, " if g.num_points else ""
            lines.append(f"graph:      {name}: 3-D, {len(g.pose_ids)} poses, {g.num_pose_edges} edges, {points}"
                         f"{g.num_pose_priors} priors (read in {self.read_seconds:.3f} s)")
        else:
            lines.append(f"graph:      {name}: {len(g.pose_ids)} poses, {len(g.point_ids)} points, "
                         f"{g.num_pose_edges} pose edges, {g.num_point_edges} point edges "
                         f"(read in {self.read_seconds:.3f} s)")
            if r.equivalences:
                lines.append(f"            {r.equivalences} TORO EQUIV records: {r.merged_vertices} vertices "
                             f"merged into others, {r.collapsed_edges} edges between them dropped")
        if r.repaired_rows:
            lines.append(f"            {r.repaired_rows} edges with an information matrix not positive definite: "
                         f"eigenvalues raised to {pg.INFORMATION_EIGENVALUE_FLOOR:g} of the largest "
                         f"(first at line {r.repaired_lines[0]})")
        return "\n".join(lines)

    def _solver(self) -> dict:
        """The fields of SparseCholeskyOptions the options name (linear_solver is its method)."""
        return {name: value for name, value in (("method", self.options.linear_solver),
                                                ("ordering", self.options.ordering)) if value is not None}

    def start(self) -> None:
        """Moves the graph to its starting point (nothing for init ``file``)."""
        t = time.perf_counter()
        if self.init == "chordal":
            pg.initialize_chordal(self.graph, **self._solver())
        elif self.init != "file" and self.dimension == 3:
            pg.initialize_odometry(self.graph)
        elif self.init != "file":
            steps = {} if self.options.poses_per_step is None else {"poses_per_step": self.options.poses_per_step}
            pg.initialize(self.graph, self.init, **steps)
        self.init_seconds = time.perf_counter() - t
        self.initial_poses = self.graph.poses
        self.initial_chi2 = self.graph.chi2()

    def start_summary(self) -> str:
        """The start and its chi2, in a line ("" for the file's own values)."""
        if self.init == "file":
            return ""
        why = f" ({self.init_reason})" if self.init_reason else ""
        return f"init:       {self.init}{why} in {self.init_seconds:.3f} s, chi2 {self.initial_chi2:.6f}"

    def optimize(self, on_iteration: Optional[Callable[[int, float], bool]] = None,
                 progress: Optional[bool] = False) -> None:
        """Optimises from the start; ``on_iteration(iteration, chi2)`` after each iteration
        (False stops); ``progress``: a bar over the iterations with chi2 beside it (None: on a
        terminal only). Ctrl-C keeps the last completed iteration's values (``interrupted``)."""
        if self.initial_poses is None:
            self.start()
        o = self.options
        with progress_bar(o.max_iterations, "optimize", "it", progress) as bar:
            def record(iteration: int, chi2: float) -> bool:
                self.chi2_history.append(chi2)
                bar.set_postfix_str(f"chi2 {chi2:.6g}", refresh=False)
                bar.update(1)
                return True if on_iteration is None else on_iteration(iteration, chi2)

            kernel_width = {} if o.kernel_width is None else {"kernel_width": o.kernel_width}
            t = time.perf_counter()
            try:
                self.report = pg.optimize(self.graph, algorithm=o.algorithm, max_iterations=o.max_iterations,
                                          kernel=o.kernel, linear_solver=self._solver(), callback=record,
                                          **kernel_width)
            except KeyboardInterrupt:
                self.interrupted = True  # the graph holds the last completed iteration's values
            self.optimize_seconds = time.perf_counter() - t

    @property
    def converged(self) -> bool:
        """Whether the optimiser stopped by its tolerances (not by the iteration limit or Ctrl-C)."""
        return self.report is not None and bool(self.report.converged)

    def optimize_summary(self) -> str:
        """chi2 before, at each iteration (with its time) and after, and why it stopped."""
        lines = [f"chi2:       {self.initial_chi2:.6f} initially"]
        seconds = self.report.iteration_seconds if self.report is not None else [math.nan] * len(self.chi2_history)
        for i, (chi2, sec) in enumerate(zip(self.chi2_history, seconds), 1):
            lines.append(f"  iteration {i:3d}: chi2 {chi2:.6f}" + (f"  ({sec * 1e3:.2f} ms)" if math.isfinite(sec) else ""))
        if self.report is None:
            lines.append(f"result:     interrupted: chi2 {self.graph.chi2():.6f} after {len(self.chi2_history)} completed "
                         f"iterations (written as it is); optimisation {self.optimize_seconds:.3f} s")
        else:
            total = self.read_seconds + self.init_seconds + self.optimize_seconds
            lines.append(f"result:     chi2 {self.report.chi2:.6f} after {self.report.iterations} iterations "
                         f"({self.report.stop_reason}); optimisation {self.optimize_seconds:.3f} s, file to result "
                         f"{total:.3f} s")
        return "\n".join(lines)

    def trajectory(self):
        """(times, poses) of the graph's poses in id order, the ids as times."""
        order = np.argsort(self.graph.pose_ids, kind="stable")
        return np.asarray(self.graph.pose_ids, dtype=float)[order], self.graph.poses[order]

    def write(self, prefix: str, trajectory_format: str = "tum") -> List[str]:
        """Writes PREFIX.g2o (the graph) and PREFIX_trajectory.EXT; returns the paths written."""
        if self.dimension == 3 and trajectory_format == "xyt":
            raise ValueError("trajectory_format xyt ('t x y theta') cannot hold a 3-D pose: use tum or kitti")
        (pg.write_g2o_3d if self.dimension == 3 else pg.write_g2o)(self.graph, prefix + ".g2o")
        times, poses = self.trajectory()
        path = prefix + "_trajectory" + io.trajectory.EXTENSIONS[trajectory_format]
        write = io.write_trajectory_3d if self.dimension == 3 else io.write_trajectory
        return [prefix + ".g2o", *write(times, poses, path, format=trajectory_format)]

    def title(self) -> str:
        """The picture's title: the file, the solver, the start and chi2 before and after."""
        start = "" if self.init == "file" else " from " + self.init
        return (f"probslam optimize: {os.path.basename(self.path)}\n{self.options.algorithm}{start}, chi2 "
                f"{self.initial_chi2:.4g} -> {self.graph.chi2():.4g} in {len(self.chi2_history)} iterations"
                + (" (interrupted)" if self.interrupted else ""))

    def draw(self, plt, edges: bool = False):
        """A figure of the graph over its start (matplotlib's pyplot given): top and side views in
        3-D."""
        if self.dimension == 3:
            from ..plot import pose_graph_3d

            fig, (top, side) = plt.subplots(1, 2, figsize=(14, 7))
            pose_graph_3d(top, side, self.graph, initial=self.initial_poses, edges=edges)
            fig.suptitle(self.title(), fontsize="medium")
        else:
            from ..plot import pose_graph

            fig, ax = plt.subplots(figsize=(8, 8))
            pose_graph(ax, self.graph, initial=self.initial_poses, edges=edges)
            ax.set_title(self.title(), fontsize="medium")
        return fig


def _noise_convention(path: str, options: GraphFileOptions) -> str:
    """The reader's noise convention: the option, or for ``auto`` the format's own, but
    covariance for an iSAM file named as GTSAM's copies are (``io.isam_noise_convention``), so
    that GTSAM's victoria_park.txt reads as it is written."""
    if options.noise != "auto":
        return options.noise
    if isam_noise_convention(path) != "covariance":
        return "default"
    with open(path, "r", errors="replace") as f:
        first = next((line.split()[0] for line in f if line.strip() and not line.lstrip().startswith("#")), "")
    if options.format == "isam" or (options.format == "auto" and first in ISAM_ONLY_RECORDS):
        return "covariance"
    return "default"


def optimize_file(path: PathLike, options: Optional[GraphFileOptions] = None,
                  on_iteration: Optional[Callable[[int, float], bool]] = None) -> GraphFileRun:
    """Reads, starts and optimises the graph file at ``path``; the run with its figures."""
    run = GraphFileRun.read(path, options)
    run.start()
    run.optimize(on_iteration)
    return run


__all__ = ["DEFAULT_INIT", "GraphFileOptions", "GraphFileRun", "INITIALIZATIONS", "LANDMARK_GRAPH_INIT",
           "NOISE_CONVENTIONS", "optimize_file"]
