"""A trajectory file scored against a ground truth: the absolute or relative trajectory error
against a reference trajectory (as evo_ape / evo_rpe print them), the relations error against a
Freiburg relations file, or the position error against ``t x y`` fixes (a GPS track); a CARMEN log
with corrected poses is a reference trajectory (its laser poses at its scans' times), or with the
raw log the estimate was made from, scored scan for scan (``eval.corrected_log_error``: its scans
paired with the raw log's by identical ranges and logger time).

``evaluate_trajectory(estimate, reference, options)`` runs it all; ``TrajectoryEvaluation`` runs
it step by step for a caller that reports each step (``probslam eval``): ``read_estimate``,
``read_reference``, ``score``; ``summary`` and ``draw`` present it. Options travel as one
``EvaluationOptions``; every refusal names its field, every file's error the file
(``inputs.reading``).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import List, Optional, Union

import numpy as np

from ._options import Options, described
from .. import eval as evaluation
from .. import io
from ..io.laser_log import read_carmen_scans
from .._args import positive_real, require_instance
from ..io.trajectory import POSITION_FIELDS, TRAJECTORY_FORMATS, first_row_fields
from ..slam import scans_of
from .inputs import CARMEN_LOG, REFERENCE_FILES, TRAJECTORY_FILE, reading

PathLike = Union[str, "os.PathLike[str]"]

#: What a reference file may be: ``auto`` tells it by its name and rows (``reference_kind``).
REFERENCE_FORMATS = ("auto",) + TRAJECTORY_FORMATS + ("relations", "carmen")
#: The kinds of reference, as ``reference_kind`` tells them.
REFERENCE_KINDS = ("trajectory", "relations", "positions", "carmen")
#: The names of CARMEN logs (after a .gz, .bz2 or .xz suffix): read as a reference's laser poses.
CARMEN_SUFFIXES = (".log", ".clf")
#: How a row of the summary starts: its label, padded to this width.
LABEL_WIDTH = 15


@dataclass
class EvaluationOptions(Options):
    """How ``evaluate_trajectory`` scores an estimate."""

    reference_format: str = described("auto", "what the reference is (auto: ``reference_kind``, a relations file by "
                                      "'.relations' in its name, a CARMEN log by .log / .clf, else the trajectory "
                                      "format its rows show)", choices=REFERENCE_FORMATS)
    rpe: bool = described(False, "the relative pose error over consecutive pairs ``delta`` apart, not the absolute "
                                 "error")
    delta: Optional[float] = described(None, "with ``rpe``: the pairs' distance (None: 1)", type=float)
    delta_unit: Optional[str] = described(None, "with ``rpe``: ``delta`` in poses, metres travelled or seconds "
                                                "(None: frames)", choices=evaluation.DELTA_UNITS)
    align: Optional[bool] = described(None, "move the estimate onto the reference first, Umeyama without scale "
                                            "(None: for the absolute error, not for ``rpe``, as evo)", type=bool)
    raw_log: Optional[PathLike] = described(None, "the raw CARMEN log the estimate was made from, its rows that log's "
                                                  "scans: with a relations file, each relation time is moved onto "
                                                  "the logger time of the scan it names; with a corrected CARMEN log, "
                                                  "its scans are paired with the raw log's by identical ranges and "
                                                  "logger times within max_time_difference", type=str)
    max_time_difference: Optional[float] = described(None, "poses are paired with the nearest reference pose at most "
                                                           "this far in time (None: 0.01, evo's)", "s", type=float)

    def validate(self) -> None:
        """ValueError / TypeError naming the first field that is wrong or does not apply."""
        units = (None,) + evaluation.DELTA_UNITS
        for name, choices in (("reference_format", REFERENCE_FORMATS), ("delta_unit", units)):
            if getattr(self, name) not in choices:
                raise ValueError(f"{name} must be one of {', '.join(c for c in choices if c)}, "
                                 f"got {getattr(self, name)!r}")
        for name in ("rpe", "align"):
            if getattr(self, name) is not None:
                require_instance(getattr(self, name), bool, name)
        for name in ("delta", "max_time_difference"):
            if getattr(self, name) is not None:
                positive_real(getattr(self, name), name)
        if not self.rpe and (self.delta is not None or self.delta_unit is not None):
            name = "delta" if self.delta is not None else "delta_unit"
            raise ValueError(f"{name} applies with rpe only (the absolute error takes every pose)")
        if self.unit == "frames" and self.step != int(self.step):
            raise ValueError(f"delta must be a whole number of frames with delta_unit frames, got {self.delta:g}")
        if self.raw_log is not None:
            require_instance(self.raw_log, (str, os.PathLike), "raw_log")


    @property
    def step(self) -> float:
        """delta, its default filled in."""
        return 1.0 if self.delta is None else float(self.delta)

    @property
    def unit(self) -> str:
        """delta_unit, its default filled in."""
        return "frames" if self.delta_unit is None else self.delta_unit

    @property
    def time_difference(self) -> float:
        """max_time_difference, its default filled in."""
        return evaluation.MAX_TIME_DIFFERENCE if self.max_time_difference is None else self.max_time_difference

    @property
    def aligned(self) -> bool:
        """align, its default filled in: the ATE aligns (evo_ape -a), the RPE does not."""
        return self.align if self.align is not None else not self.rpe

    def check_reference(self, kind: str) -> None:
        """ValueError naming the first option that does not apply to a reference of ``kind``."""
        why = {"relations": "relative poses need no alignment, and the estimate is interpolated at each relation's "
                            "times",
               "positions": "the estimate is interpolated at each fix's time, and the error printed both as it is and "
                            "after the alignment"}.get(kind)
        for name in ("rpe", "align", "max_time_difference"):
            if why and getattr(self, name) not in (None, False):
                raise ValueError(f"{name} applies to a reference trajectory, not to {kind} ({why})")
        if kind not in ("relations", "carmen") and self.raw_log is not None:
            raise ValueError("raw_log applies to a relations file (the raw log whose ipc time stamps it) or a "
                             "corrected CARMEN log (the raw log whose scans it corrects)")
        if kind == "carmen" and self.raw_log is not None and (self.rpe or self.align is False):
            raise ValueError(f"{'rpe' if self.rpe else 'align'}: with raw_log a corrected log is compared scan for "
                             "scan, its absolute poses after the rigid alignment")


def reference_kind(path: PathLike, reference_format: str = "auto") -> str:
    """What the reference at ``path`` is (REFERENCE_KINDS): with ``reference_format`` auto, a
    relations file when its name has '.relations', a CARMEN log when it ends in .log or .clf
    (optionally .gz/.bz2/.xz), positions when its first row is ``t x y``, else a trajectory."""
    if reference_format in ("relations", "carmen"):
        return reference_format
    if reference_format != "auto":
        return "trajectory"
    name = os.path.basename(os.fspath(path)).lower()
    if ".relations" in name:
        return "relations"
    for suffix in (".gz", ".bz2", ".xz"):
        name = name.removesuffix(suffix)
    if name.endswith(CARMEN_SUFFIXES):
        return "carmen"
    return "positions" if first_row_fields(path) == POSITION_FIELDS else "trajectory"


def _row(label: str, text: str) -> str:
    return f"{label:<{LABEL_WIDTH}}{text}"


def _trajectory_line(label: str, path: str, trajectory: io.Trajectory) -> str:
    """A trajectory file as read: its poses, format and what was skipped or projected."""
    notes = [f"{trajectory.skipped_rows} unreadable rows skipped"] if trajectory.skipped_rows else []
    if trajectory.projected_rows:
        notes.append(f"{trajectory.projected_rows} non-planar rows read as their 2-D projection")
    if trajectory.times_from_index:
        notes.append("no times file: the row index is the time")
    return _row(label, f"{path}: {len(trajectory)} poses ({trajectory.format.upper()}"
                       f"{'; ' + '; '.join(notes) if notes else ''})")


@dataclass
class TrajectoryEvaluation:
    """One estimate scored against one reference, step by step; each step's figures are fields,
    ``estimate_summary``, ``reference_summary`` and ``summary`` say them in lines (``notes``:
    what the caller should be told besides, e.g. on stderr)."""

    options: EvaluationOptions
    estimate_path: str
    estimate: io.Trajectory
    reference_path: Optional[str] = None
    kind: Optional[str] = None
    reference: object = None  # io.Trajectory, io.Positions or eval.Relations
    corrected: object = None  # a CARMEN reference's io.LaserScans
    raw: object = None  # with raw_log and a CARMEN reference: the raw log's io.LaserScans
    clock: str = ""  # how the relations' times were moved onto the estimate's clock
    notes: List[str] = field(default_factory=list)
    result: object = None  # eval.TrajectoryError, RelationsError, PositionError or CorrectedLogError

    @classmethod
    def read_estimate(cls, path: PathLike, options: Optional[EvaluationOptions] = None) -> "TrajectoryEvaluation":
        """Reads the estimate (``io.read_trajectory``: TUM, KITTI or ``t x y theta``)."""
        options = EvaluationOptions() if options is None else options
        require_instance(options, EvaluationOptions, "options")
        options.validate()
        path = os.fspath(path)
        with reading(path, TRAJECTORY_FILE):
            return cls(options, path, io.read_trajectory(path))

    def estimate_summary(self) -> str:
        """The estimate as read, in a line: its poses, format and what was skipped."""
        return _trajectory_line("estimate:", self.estimate_path, self.estimate)

    def read_reference(self, path: PathLike) -> None:
        """Tells what the reference at ``path`` is (``reference_kind``), refuses an option that
        does not apply to it (ValueError naming the field), reads it and puts it on the
        estimate's clock (``_match_clocks``)."""
        path = os.fspath(path)
        with reading(path, TRAJECTORY_FILE):  # its name or first row tells what it is
            kind = reference_kind(path, self.options.reference_format)
        self.options.check_reference(kind)
        self.reference_path, self.kind = path, kind
        with reading(path, REFERENCE_FILES[kind]):
            self._read_reference()
        self._match_clocks()

    def _read_reference(self) -> None:
        path, kind = self.reference_path, self.kind
        if kind == "relations":
            self.reference = evaluation.read_relations(path)
        elif kind == "positions":
            self.reference = io.read_positions(path)
        elif kind == "carmen":
            self.corrected = read_carmen_scans(path).scans
            self.reference = io.Trajectory(self.corrected.timestamps, self.corrected.laser_poses, "carmen")
        elif self.options.reference_format == "auto":
            self.reference = io.read_trajectory(path)
        else:
            self.reference = io.read_trajectory(path, format=self.options.reference_format)

    def _match_clocks(self) -> None:
        """Relations onto the estimate's clock; a CARMEN log's times checked against the
        estimate's (with ``raw_log``: its scans read, the estimate's rows checked to be them,
        ``_raw_scans``). The Freiburg relations are stamped with the raw log's ipc time, the commands
        write its logger time: with ``raw_log``, each relation time is moved onto the logger time
        of the scan it names; without, by the one constant offset that makes every relation time
        a time of the estimate (``eval.clock_offset``) when there is one, else left as they are
        with a note when none of them is a time of the estimate. A corrected CARMEN log (Intel's,
        FR079's) carries its raw log's logger time: ValueError when its times do not overlap the
        estimate's (an estimate on another clock, such as the ipc time, or of another log)."""
        if self.kind == "carmen":
            self._check_overlap()
            if self.options.raw_log is not None:
                self._raw_scans()
        if self.kind != "relations":
            return
        relations, o = self.reference, self.options
        if o.raw_log is not None:
            with reading(os.fspath(o.raw_log), CARMEN_LOG, files={"scans": os.fspath(o.raw_log)}):
                moved = evaluation.relations_on_logger_time(relations, scans_of(o.raw_log))
            shift = float(np.median(relations.t1 - moved.t1))
            self.clock = (f"times moved from {os.fspath(o.raw_log)}'s ipc time to its logger time ({shift:.6f} s "
                          "earlier)")
            self.reference = moved
            return
        times = np.sort(self.estimate.timestamps)
        stamps = np.concatenate([relations.t1, relations.t2])
        offset = evaluation.clock_offset(times, stamps)
        if offset:
            self.clock = (f"times moved {offset:.6f} s earlier, onto the estimate's clock (each is then a time of the "
                          "estimate: the relations are stamped with the raw log's ipc time, 'slam' writes its logger "
                          "time)")
            self.reference = dataclasses.replace(relations, t1=relations.t1 - offset, t2=relations.t2 - offset)
        elif offset is None and not np.any(evaluation.on_times(times, stamps)):
            self.notes.append(f"none of {self.reference_path}'s times is a time of {self.estimate_path}: a Freiburg "
                              "relations file is stamped with its raw log's ipc time, while 'slam' writes the log's "
                              "logger time; give that log with --log (e.g. --log aces.clf.bz2)")

    def _raw_scans(self) -> None:
        raw_log = os.fspath(self.options.raw_log)
        with reading(raw_log, CARMEN_LOG):
            self.raw = read_carmen_scans(raw_log).scans
        te, tr = self.estimate.timestamps, self.raw.timestamps
        if len(te) > len(tr):
            why = f"{len(te)} poses, {len(tr)} scans"
        else:  # the times as written (io.write_trajectory: to 1 ns; a log: to 1 us) are the scans'
            off = np.flatnonzero(np.abs(te - tr[:len(te)]) > evaluation.SAME_SCAN_TIME)
            if not off.size:
                return
            why = f"row {off[0]} at {te[off[0]]:.9g} s, scan {off[0]} at {tr[off[0]]:.9g} s"
        raise ValueError(f"{self.estimate_path}: its rows are not {raw_log}'s scans in order ({why}): with raw_log "
                         "the estimate holds a pose for each of its scans from the first, as 'slam' writes them")

    def _check_overlap(self) -> None:
        t, te, slack = self.reference.timestamps, self.estimate.timestamps, self.options.time_difference
        if te.max() < t.min() - slack or te.min() > t.max() + slack:
            raise ValueError(f"{self.reference_path}: its scans' times [{t.min():.9g}, {t.max():.9g}] s do not overlap "
                             f"the estimate's [{te.min():.9g}, {te.max():.9g}] s: a corrected log (Intel's, FR079's) "
                             "is stamped with its raw log's logger time (each line's last field), as the commands "
                             "write a log's poses; the estimate is on another clock (the ipc time?) or of another log")

    def reference_summary(self) -> str:
        """The reference as read (after the relations' clock line, when they were moved)."""
        ref, path = self.reference, self.reference_path
        if self.kind == "relations":
            return "\n".join(([_row("relations:", self.clock)] if self.clock else [])
                             + [_row("reference:", f"{path}: {len(ref)} relations"
                                     + (f" ({ref.skipped_rows} unreadable rows skipped)" if ref.skipped_rows else ""))])
        if self.kind == "positions":
            return _row("reference:", f"{path}: {len(ref)} positions (t x y"
                        + (f"; {ref.skipped_rows} unreadable rows skipped)" if ref.skipped_rows else ")"))
        if self.kind == "carmen":
            return _row("reference:", f"{path}: {len(ref)} poses (CARMEN log: the laser poses of its scans)"
                        + (f"\n{_row('raw log:', f'{os.fspath(self.options.raw_log)}: {len(self.raw)} scans')}"
                           if self.raw is not None else ""))
        if self.options.reference_format == "auto":
            return _trajectory_line("reference:", path, ref)
        return _row("reference:", f"{path}: {len(ref)} poses ({ref.format.upper()})")

    @property
    def align(self) -> str:
        """The alignment of a trajectory score: "se2" or "none"."""
        return "se2" if self.options.aligned else "none"

    def score(self):
        """The error of the estimate against the reference (``eval.relations_error``,
        ``eval.position_error``, ``eval.rpe`` or ``eval.ate``). An error about the estimate or the
        reference names its file (those functions' parameters told as the files they were read
        from), one about an option its field (``delta: ...``)."""
        est_path, ref_path = self.estimate_path, self.reference_path
        files = {**dict.fromkeys(("times_est", "poses_est", "timestamps", "poses"), est_path),
                 "times_ref": ref_path, "poses_ref": ref_path, "relations": "relations", "corrected": ref_path}
        if self.options.raw_log is not None:
            files["raw"] = os.fspath(self.options.raw_log)
        with reading(est_path, TRAJECTORY_FILE, [f.name for f in dataclasses.fields(EvaluationOptions)], files=files):
            return self._score()

    def _score(self):
        est, ref, o = self.estimate, self.reference, self.options
        if self.kind == "relations":
            self.result = evaluation.relations_error(est.timestamps, est.poses, ref)
        elif self.kind == "positions":
            self.result = evaluation.position_error(est.timestamps, est.poses, ref.timestamps, ref.positions)
        elif self.raw is not None:
            self.result = evaluation.corrected_log_error(est.poses, self.raw, self.corrected, o.time_difference)
        elif o.rpe:
            self.result = evaluation.rpe(est.timestamps, est.poses, ref.timestamps, ref.poses, delta=o.step,
                                         delta_unit=o.unit, align=self.align, max_time_difference=o.time_difference)
        else:
            self.result = evaluation.ate(est.timestamps, est.poses, ref.timestamps, ref.poses, align=self.align,
                                         max_time_difference=o.time_difference)
        return self.result

    def summary(self) -> str:
        """The score: what was paired, then evo's statistics tables."""
        r, o = self.result, self.options
        if self.kind == "relations":
            return (_row("relations:", f"{len(r.used)} used, {r.skipped} outside the estimate's time span\n\n")
                    + evaluation.statistics_table("relations error w.r.t. translation part (m)",
                                                  evaluation.error_statistics(r.translational)) + "\n"
                    + evaluation.statistics_table("relations error w.r.t. rotation angle in degrees (deg)",
                                                  evaluation.error_statistics(np.degrees(r.rotational))))
        if isinstance(r, evaluation.CorrectedLogError):
            outside = f"; {r.outside} past the estimate's last scan" if r.outside else ""
            return (_row("paired:", f"{r.pairs} with {os.fspath(o.raw_log)}'s scans (identical ranges, logger times "
                                    f"within {r.pairs.tolerance:g} s){outside}\n\n") + str(r))
        if self.kind == "positions":
            return (_row("fixes:", f"{r.count} used, {r.outside} outside the estimate's time span (the estimate is "
                                   "interpolated at each fix's time)\n\n") + str(r))
        return (_row("associated:", f"{r.matched} of {min(len(self.estimate), len(self.reference))} possible pose "
                                    f"pairs within {o.time_difference:g} s")
                + (f"; {r.count} relative pairs" if o.rpe else "") + "\n\n" + str(r))

    def draw(self, plt):
        """A figure (matplotlib's pyplot given): the reference and the estimate on metre axes, the
        estimate moved by the alignment when one was made, and the error per pose, pair or fix."""
        est, ref, r = self.estimate, self.reference, self.result
        fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 6), gridspec_kw=dict(width_ratios=(3, 2)))
        xy = est.poses[:, :2]
        if self.kind != "relations":
            xy = xy @ r.rotation.T + r.translation
            ref_xy = ref.positions if self.kind == "positions" else ref.poses[:, :2]
            ax.plot(ref_xy[:, 0], ref_xy[:, 1], ".", ms=2, color="0.4", label=f"reference ({self.kind})")
        ax.plot(xy[:, 0], xy[:, 1], "-", lw=1, color="tab:blue",
                label="estimate" + (" (aligned)" if self.kind != "relations" and self.align != "none" else ""))
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.legend(fontsize="small")
        ax.set_title(f"{os.path.basename(self.estimate_path)} against {os.path.basename(self.reference_path)}",
                     fontsize="medium")
        errors = r.translational if self.kind == "relations" else r.errors
        bx.plot(errors, color="tab:red", lw=1)
        each = "pair" if self.options.rpe else "pose"
        bx.set_xlabel({"relations": "relation", "positions": "fix"}.get(self.kind, each))
        bx.set_ylabel("translational error [m]")
        return fig


def evaluate_trajectory(estimate: PathLike, reference: PathLike,
                        options: Optional[EvaluationOptions] = None) -> TrajectoryEvaluation:
    """Scores the trajectory file ``estimate`` against ``reference`` (a trajectory file, a
    relations file, a CARMEN log with corrected poses or ``t x y`` positions) with ``options``;
    the evaluation with its result (``notes``: what a caller should say besides the summary). A file
    that is not what it should be is an InputError naming it (``inputs.reading``)."""
    run = TrajectoryEvaluation.read_estimate(estimate, options)
    run.read_reference(reference)
    run.score()
    return run


__all__ = ["CARMEN_SUFFIXES", "EvaluationOptions", "REFERENCE_FORMATS", "REFERENCE_KINDS", "TrajectoryEvaluation",
           "evaluate_trajectory", "reference_kind"]
