"""3-D pose-graph optimisation: probslam's PoseGraph3D beside GTSAM (pip `gtsam`, a peer, not a
dependency) on the shipped 3-D graphs, in the same run.

For each graph and each start (the file's values; a chordal rotation initialisation, probslam's
`initialize_chordal` and GTSAM's `InitializePose3`): both libraries' Levenberg-Marquardt, the
file-to-result time (read, initialise, optimise), iterations and final chi2. GTSAM's first pose
gets a tight prior (sigma 1e-6), as bench_pose_graph.py does in 2-D: the gauge; probslam holds the
first pose. The chi2 reported leaves GTSAM's prior out.

The two libraries minimise slightly different objectives (sums over edges of e^T Omega e, no 1/2):
probslam's e = [t_e, Log(R_e)] of z^-1 x_i^-1 x_j (g2o's translation error with the rotation vector),
GTSAM's e = Log(z^-1 x_i^-1 x_j) in SE(3)'s exponential coordinates (translation V^-1 t_e): the same
to first order, different at second order in the rotation error times the translation. So each
result is evaluated in both objectives, and "probslam at or below GTSAM" is read in each column
like for like. The file's information applies to [translation, rotation vector] in both, as GTSAM's
readG2o and SE-Sync read it (g2o's own EdgeSE3 puts the rotation block on the error quaternion's
vector part, half the angle: g2o's chi2 of the same poses weights rotation errors 4x less).
tests/python/test_pose_graph_file_3d.py checks a dense numpy version of GTSAM's chi2 against
GTSAM's on the initial values.

SE-Sync (Rosen et al., IJRR 2019) minimises F = sum kappa_ij ||R_j - R_i R_ij||_F^2
+ tau_ij ||t_j - t_i - R_i t_ij||^2 with isotropic weights made from the g2o information (its
g2o reader: tau = 3 / tr(I_t^-1), kappa = 3 / (2 tr(I_R^-1)), I_t and I_R the diagonal blocks of
Omega). For a rotation error of angle theta, ||R_a - R_b||_F^2 = 4 (1 - cos theta) = 2 theta^2 + O(theta^4),
so with Omega = diag(tau I, omega I) (kappa = omega / 2) F's rotation term is omega theta^2 to
fourth order, and its translation term is tau |R_ij^T (R_i^T (t_j - t_i) - t_ij)|^2: the plain
translation error, not GTSAM's V^-1 t, which differs at second order in theta |t|. So where the
information is isotropic per block (torus3D: 100 I, 400 I; pose3example: 1e4 I) and residuals
small, F at the optimum equals this chi2 to a few digits. Where it is not (sphere2500.g2o's
rotation block is about diag(407, 398, 104) with off-diagonal terms; parking-garage's is near
4 I with small off-diagonal terms), SE-Sync optimises a slightly different objective and its
optimum is a reference, not a bound.

With --certify (a table of its own; the timing table is not run): for each graph, probslam's
optimum from the chordal start is refined in SE-Sync's objective and certified globally optimal by
SE-Sync's test (probslam.certificate: the certificate matrix S = M - Lambda positive
semidefinite, lambda_min(S) >= -eta); then probslam's optimiser (its own objective) is started from
that certified point, and its chi2 compared with the one from the chordal start. The certificate
is for SE-Sync's objective, not probslam's: the link is that re-run.

    python benchmarks/bench_pose_graph_3d.py [--repeat 3] [--quick] [--record] [--certify]
"""

import argparse
import datetime
import importlib.metadata
import pathlib
import statistics
import sys
import time

import probslam
from common import machine, report

DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "pose_graphs"
DATASETS = {
    "pose3example (GTSAM)": DATA / "gtsam_examples" / "pose3example.txt",
    "sphere2500": DATA / "sphere2500" / "sphere2500.g2o",
    "parking-garage": DATA / "parking_garage" / "parking-garage.g2o",
    "torus3D": DATA / "torus3d" / "torus3D.g2o",
}
# sphere2500.txt (iSAM's EDGE3) is left out: GTSAM's load3D reads its square-root information as
# information, and the file lists no initial values.

# Two runs of probslam's optimiser reach "the same" optimum when their chi2 agree to this fraction:
# both stop when an iteration gains less than RELATIVE_TOLERANCE (1e-10) of chi2.
SAME_OPTIMUM = 1e-9

# Levenberg-Marquardt stops when an iteration changes the error by less than this fraction
# (bench_pose_graph.py's value).
RELATIVE_TOLERANCE = 1e-10
MAX_ITERATIONS = 100
# The gauge: a prior this tight on the first pose holds it as a fixed vertex would.
PRIOR_SIGMA = 1e-6


def gtsam_pose(row):
    """A probslam pose row [x, y, z, qx, qy, qz, qw] as a gtsam.Pose3."""
    import gtsam

    return gtsam.Pose3(gtsam.Rot3.Quaternion(row[6], row[3], row[4], row[5]), gtsam.Point3(*row[:3]))


def probslam_row(pose):
    """A gtsam.Pose3 as a probslam pose row."""
    q = pose.rotation().toQuaternion()
    t = pose.translation()
    return [t[0], t[1], t[2], q.x(), q.y(), q.z(), q.w()]


def run_gtsam(path, initialisation):
    """(seconds file to result, iterations, chi2 of the result, chi2 of the start, the result as
    {key: pose row}, the factor graph without the gauge prior)."""
    import gtsam

    t0 = time.perf_counter()
    graph, initial = gtsam.readG2o(str(path), True)
    first = min(initial.keys())
    anchored = gtsam.NonlinearFactorGraph(graph)
    anchored.add(gtsam.PriorFactorPose3(first, initial.atPose3(first), gtsam.noiseModel.Isotropic.Sigma(6, PRIOR_SIGMA)))
    if initialisation == "chordal":
        initial = gtsam.InitializePose3.initialize(anchored)
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(RELATIVE_TOLERANCE)
    params.setAbsoluteErrorTol(0.0)
    params.setMaxIterations(MAX_ITERATIONS)
    optimizer = gtsam.LevenbergMarquardtOptimizer(anchored, initial, params)
    result = optimizer.optimize()
    seconds = time.perf_counter() - t0
    poses = {int(k): probslam_row(result.atPose3(k)) for k in result.keys()}
    return seconds, optimizer.iterations(), 2 * graph.error(result), 2 * graph.error(initial), poses, graph


def run_probslam(path, initialisation, algorithm):
    """(seconds file to result, iterations, chi2 of the result, chi2 of the start, the graph at the
    result, {phase: seconds}): the file read into a PoseGraph3D in C++, probslam's chordal
    initialisation (Carlone et al. 2015) when asked, then `algorithm` with GTSAM's tolerances and
    the 3-D defaults (CHOLMOD's analysis, METIS, supernodal factorisation). The first pose is
    held (fixed), as GTSAM's tight prior holds it."""
    t0 = time.perf_counter()
    graph = probslam.graph.read_pose_graph_3d(path)
    t_read = time.perf_counter()
    if initialisation == "chordal":
        probslam.graph.initialize_chordal(graph)
    t_init = time.perf_counter()
    r = probslam.graph.optimize(graph, algorithm=algorithm, relative_tolerance=RELATIVE_TOLERANCE,
                                max_iterations=MAX_ITERATIONS)
    t_end = time.perf_counter()
    phases = {"read": t_read - t0, "init": t_init - t_read, "optimise": t_end - t_init,
              "iterations": sum(r.iteration_seconds)}
    return t_end - t0, r.iterations, r.chi2, r.initial_chi2, graph, phases


def in_probslam_objective(graph, poses):
    """probslam's chi2 ([t, Log R] of z^-1 x_i^-1 x_j) of GTSAM's result."""
    g = graph.copy()
    ids = g.pose_ids
    g.set_poses(ids, [poses[int(i)] for i in ids])
    return g.chi2()


def in_gtsam_objective(factors, graph):
    """GTSAM's chi2 (2 x error, SE(3) log) of probslam's result."""
    import gtsam

    values = gtsam.Values()
    for i, row in zip(graph.pose_ids, graph.poses):
        values.insert(int(i), gtsam_pose(row))
    return 2 * factors.error(values)


def median_run(fn, repeat, *args):
    """The run with the median time (its result and chi2 with it)."""
    runs = sorted((fn(*args) for _ in range(repeat)), key=lambda r: r[0])
    return runs[len(runs) // 2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="one run, the two smallest graphs, nothing recorded")
    parser.add_argument("--record", action="store_true",
                        help="write the table into benchmarks/RESULTS.md (replacing its previous run)")
    parser.add_argument("--certify", action="store_true",
                        help="instead of the timing table: certify each graph's optimum by SE-Sync's test "
                             "(needs scipy) and re-run probslam from the certified point")
    args = parser.parse_args()
    datasets = {k: v for k, v in DATASETS.items() if v.exists()}
    try:
        import gtsam
    except ImportError:
        if not args.certify:
            sys.exit("bench_pose_graph_3d: needs `pip install gtsam`")
    else:
        # A graph from the peer's own package, never used to tune anything here.
        grid = pathlib.Path(gtsam.__file__).parent / "Data" / "pose3example-grid.txt"
        if grid.exists():
            datasets["pose3example-grid (GTSAM's Data)"] = grid
    if not datasets:
        print(f"bench_pose_graph_3d: no datasets under {DATA}; nothing to do")
        return
    if args.quick:
        datasets = dict(list(datasets.items())[:2])
    if args.certify:
        certify_main(datasets, record=args.record and not args.quick)
        return
    repeat = 1 if args.quick else args.repeat
    lines = [f"## 3-D pose-graph optimisation against GTSAM, {datetime.date.today()}", "",
             f"Machine: {machine()}, shared with other jobs (times vary by about 20 % from run to run); "
             f"gtsam {importlib.metadata.version('gtsam')} (pip). probslam's Gauss-Newton (its default) and "
             f"Levenberg-Marquardt, GTSAM's Levenberg-Marquardt, relative tolerance {RELATIVE_TOLERANCE:g}, at "
             f"most {MAX_ITERATIONS} iterations, run one after the other in one process; of {repeat} runs the one "
             "of median time. File to result = read + initialise + optimise. chi2 in each objective: probslam's, "
             "e = [t, Log R] of z^-1 x_i^-1 x_j, and GTSAM's, e = Log(z^-1 x_i^-1 x_j) in SE(3)'s exponential "
             "coordinates (2 x its error, gauge prior left out); every result is evaluated in both.", "",
             "| dataset | start | file to result: probslam GN / LM / GTSAM LM | ratio to GTSAM: GN / LM | "
             "iterations: GN / LM / GTSAM | chi2, probslam's objective: GN / LM / GTSAM's result | "
             "chi2, GTSAM's objective: GN / LM / GTSAM's result |",
             "|---|---|---|---|---|---|---|"]
    phase_lines = ["", "Where probslam's time goes (the Gauss-Newton runs): read the file into a PoseGraph3D, "
                   "initialise, optimise (of which the iterations' own time: factor, solve, update, linearise; "
                   "the first also makes CHOLMOD's analysis, the ordering; the rest is the first linearisation "
                   "and the copy the optimiser works on).", "",
                   "| dataset | start | read | initialise | optimise | iterations | per iteration | chi2 at start |",
                   "|---|---|---|---|---|---|---|---|"]
    for name, path in datasets.items():
        for initialisation in ("file", "chordal"):
            theirs = median_run(run_gtsam, repeat, path, initialisation)
            gn = median_run(run_probslam, repeat, path, initialisation, "gauss-newton")
            lm = median_run(run_probslam, repeat, path, initialisation, "levenberg-marquardt")
            theirs_in_ours = in_probslam_objective(gn[4], theirs[4])
            ours_in_theirs = [in_gtsam_objective(theirs[5], r[4]) for r in (gn, lm)]
            lines.append(f"| {name} | {initialisation} | {gn[0] * 1e3:.1f} / {lm[0] * 1e3:.1f} / "
                         f"{theirs[0] * 1e3:.1f} ms | {gn[0] / theirs[0]:.2f}x / {lm[0] / theirs[0]:.2f}x | "
                         f"{gn[1]} / {lm[1]} / {theirs[1]} | {gn[2]:.6f} / {lm[2]:.6f} / {theirs_in_ours:.6f} | "
                         f"{ours_in_theirs[0]:.6f} / {ours_in_theirs[1]:.6f} / {theirs[2]:.6f} |")
            p = gn[5]
            phase_lines.append(f"| {name} | {initialisation} | {p['read'] * 1e3:.1f} ms | {p['init'] * 1e3:.1f} ms | "
                               f"{p['optimise'] * 1e3:.1f} ms | {p['iterations'] * 1e3:.1f} ms | "
                               f"{p['iterations'] / max(gn[1], 1) * 1e3:.2f} ms | {gn[3]:.6g} |")
            print(lines[-1], flush=True)
    lines += phase_lines + ["", "SE-Sync's certified optima: see the record '3-D pose graphs at SE-Sync's "
                                "certified optimum' (run with --certify)."]
    report(lines, record=args.record and not args.quick)


def certify_graph(path):
    """probslam's optimum from the chordal start, refined in SE-Sync's objective and certified, and
    probslam's optimiser re-run from the certified point: a dict of the table's numbers."""
    import probslam.certificate as sc

    graph = probslam.graph.read_pose_graph_3d(path)
    probslam.graph.initialize_chordal(graph)
    ours = probslam.graph.optimize(graph, relative_tolerance=RELATIVE_TOLERANCE, max_iterations=MAX_ITERATIONS)
    p, R, t = sc.problem_from_graph(graph)
    t0 = time.perf_counter()
    refined = sc.refine(p, R, t)
    t1 = time.perf_counter()
    cert = sc.certify(p, refined.R, refined.t)
    t2 = time.perf_counter()
    again = graph.copy()
    again.set_poses(again.pose_ids, sc.poses_rows(refined.R, refined.t))
    rerun = probslam.graph.optimize(again, relative_tolerance=RELATIVE_TOLERANCE, max_iterations=MAX_ITERATIONS)
    return {"poses": p.n, "edges": len(p.i), "chi2": ours.chi2, "F_ours": refined.initial_objective,
            "F": refined.objective, "newton": refined.iterations, "gradient": refined.gradient_norm,
            "cert": cert, "chi2_at_cert": rerun.initial_chi2, "chi2_rerun": rerun.chi2,
            "rerun_iterations": rerun.iterations, "refine_s": t1 - t0, "certify_s": t2 - t1}


def certify_main(datasets, record):
    lines = [f"## 3-D pose graphs at SE-Sync's certified optimum, {datetime.date.today()}", "",
             f"Machine: {machine()}, shared with other jobs. For each graph: probslam's Gauss-Newton optimum from "
             "the chordal start (relative tolerance 1e-10); SE-Sync's objective F = sum kappa ||R_j - R_i R_ij||_F^2 "
             "+ tau ||t_j - t_i - R_i t_ij||^2 (weights from SE-Sync's g2o reader: tau = 3 / tr(I_t^-1), "
             "kappa = 3 / (2 tr(I_R^-1))) there, then refined from there by damped Newton on F "
             "(probslam.certificate; Newton iterations, |grad F| at the end); the certificate "
             "S = M - blkdiag(0, Lambda) at the refined point: lambda_min(S) (shift-invert Lanczos at a shift "
             "below it) and the verdict, certified when no eigenvalue of S is below -eta (the inertia of an "
             "LDL^T factorisation of S + eta I), eta = 1e-10 ||S||_inf; lambda_gap is S's smallest eigenvalue "
             "off its 4-dimensional null space (the global rotation and translation), the margin. Certified: "
             "the refined point is a global minimum of F (SE-Sync's relaxation is tight there). F is not "
             "probslam's chi2 (isotropic weights, chordal rotation distance), so probslam's optimiser is then "
             f"started from the certified point: its chi2 there and where it stops, against the chordal start's "
             f"(same: within {SAME_OPTIMUM:g} relative).", "",
             "| dataset | poses / edges | F at probslam's optimum | F at the certified optimum (Newton iterations, "
             "abs grad F) | lambda_min(S) / eta / certified | lambda_gap | chi2: at the certified optimum, "
             "re-optimised (iterations) / ours from chordal | same | time: refine / certify |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, path in datasets.items():
        r = certify_graph(path)
        c = r["cert"]
        diff = abs(r["chi2_rerun"] - r["chi2"]) / r["chi2"]
        lines.append(f"| {name} | {r['poses']} / {r['edges']} | {r['F_ours']:.10g} | {r['F']:.10g} ({r['newton']}, "
                     f"{r['gradient']:.1e}) | {c.lambda_min:.1e} / {c.eta:.1e} / {'yes' if c.certified else 'NO'} | "
                     f"{c.lambda_gap:.3e} | {r['chi2_at_cert']:.10g}, {r['chi2_rerun']:.10g} ({r['rerun_iterations']}) / "
                     f"{r['chi2']:.10g} | {'yes' if diff <= SAME_OPTIMUM else 'no'} ({diff:.0e}) | "
                     f"{r['refine_s']:.2f} / {r['certify_s']:.2f} s |")
        print(lines[-1], flush=True)
    report(lines, record=record)


if __name__ == "__main__":
    main()
