"""SE-Sync's objective on a 3-D pose graph, a local refinement of it and its optimality certificate
(numpy + scipy only): whether a 3-D pose graph's optimum is the global one
(benchmarks/bench_pose_graph_3d.py --certify runs it on the published graphs).

SE-Sync (Rosen, Carlone, Bandeira, Leonard, IJRR 2019) minimises

    F = sum_ij kappa_ij ||R_j - R_i R_ij||_F^2 + tau_ij ||t_j - t_i - R_i t_ij||^2,  R_i in SO(3),

with isotropic weights made from each edge's 6x6 information [[I_t, .], [., I_R]] (translation
first) as its g2o reader makes them: tau = 3 / tr(I_t^-1), kappa = 3 / (2 tr(I_R^-1)) (the inverse
of each diagonal block, not a block of the inverse: its information-divergence choice).

With X = [t_1 .. t_n | R_1 .. R_n] (3 x 4n), F = tr(X M X^T) for a sparse symmetric 4n x 4n data
matrix M (each edge adds tau a a^T, a = e_j - e_i - t_ij on R_i's columns, and kappa B B^T,
B = [I on R_j's columns, -R_ij^T on R_i's]). At a first-order critical point the multipliers of
R_i^T R_i = I are Lambda_i = Sym(R_i^T (X M)_{R_i}), and the certificate matrix is
S = M - blkdiag(0_n, Lambda_1 .. Lambda_n). S X^T = 0 and S [1_n; 0] = 0 (the global rotation and
translation: a 4-dimensional null space); if S is positive semidefinite, X is a global minimum of F
and the SDP relaxation is tight there (SE-Sync's Theorem: S >= 0 certifies optimality). The test
is lambda_min(S) >= -eta, eta a small multiple of ||S|| (ETA_RELATIVE).

lambda_min(S) without a dense eigensolver: the inertia of S - sigma I from an LDL^T-like
factorisation (SuperLU with diagonal pivots and a symmetric ordering: by Sylvester's law of inertia
the number of negative pivots is the number of eigenvalues below sigma), which both decides the
verdict (no eigenvalue below -eta) and brackets lambda_min from below; then scipy's eigsh in
shift-invert mode at a sigma just below lambda_min returns it (the nearest eigenvalue above sigma).
"""

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation

#: The certificate's tolerance eta = ETA_RELATIVE * ||S||_inf. What moves S's null eigenvalues off
#: zero: rounding in S's entries (~1e-16 ||S||), the refined point's residual stationarity
#: (||S X^T|| / (||S|| ||X||) measured 3e-17 to 5e-12 on the shipped graphs), and the LDL^T's
#: backward error (~N u ||S||, below 2e-12 ||S|| for N = 20 000): all at least 20x below 1e-10.
#: Measured null eigenvalues: |lambda| <= 1e-14 ||S||. A wrong local minimum's negative eigenvalue
#: is of the order of an edge weight (-8.4 at ||S|| ~ 400 in the test's loop), far above eta.
ETA_RELATIVE = 1e-10

#: The refinement stops when an iteration lowers F by less than this fraction of it: about
#: rounding in a sum of 10^4 positive terms (1e-16 each, relative), so further steps move nothing
#: measurable.
RELATIVE_DECREASE = 1e-14

#: Bisection for a shift below lambda_min stops once the bracket is this fraction of its lower end:
#: close enough that shift-invert Lanczos converges in a few steps.
BRACKET_RELATIVE = 1e-2

#: Newton's damping: the first value tried once the undamped step fails, and the value past which
#: no step is sought (the step is then ~1e-12 of the gradient step: nothing left to gain).
SMALLEST_DAMPING = 1e-9
LARGEST_DAMPING = 1e12

# hat(e_k) for k = x, y, z: d/dw_k of [w]x.
_GENERATORS = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
                        [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]],
                        [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])


@dataclass
class Problem:
    """A pose graph in SE-Sync's terms: edges (i, j) as indices 0..n-1 into `ids`, measured
    rotations R (E, 3, 3) and translations t (E, 3), weights kappa and tau (E,)."""
    ids: np.ndarray
    i: np.ndarray
    j: np.ndarray
    R: np.ndarray
    t: np.ndarray
    kappa: np.ndarray
    tau: np.ndarray

    @property
    def n(self) -> int:
        """The number of poses."""
        return len(self.ids)


def quaternion_to_rotation(q):
    """Unit quaternions (..., 4) [qx, qy, qz, qw] as rotation matrices (..., 3, 3)."""
    q = np.asarray(q, dtype=float)
    return Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))


def rotation_to_quaternion(R):
    """Rotation matrices (..., 3, 3) as unit quaternions (..., 4) [qx, qy, qz, qw]."""
    R = np.asarray(R, dtype=float)
    return Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[:-2] + (4,))


def se_sync_weights(information):
    """(kappa, tau) (E,) of 6x6 informations (E, 6, 6) [translation, rotation]: SE-Sync's g2o
    reader's tau = 3 / tr(I_t^-1), kappa = 3 / (2 tr(I_R^-1))."""
    info = np.asarray(information, dtype=float)
    tau = 3.0 / np.trace(np.linalg.inv(info[:, :3, :3]), axis1=1, axis2=2)
    kappa = 3.0 / (2.0 * np.trace(np.linalg.inv(info[:, 3:, 3:]), axis1=1, axis2=2))
    return kappa, tau


def problem_from_arrays(pose_ids, edge_ids, measurements, information) -> Problem:
    """A Problem from vertex ids (n,), edge (from, to) ids (E, 2), measurements (E, 7)
    [x, y, z, qx, qy, qz, qw] (the pose of `to` in `from`'s frame) and informations (E, 6, 6)."""
    pose_ids = np.asarray(pose_ids, dtype=np.int64)
    edge_ids = np.asarray(edge_ids, dtype=np.int64).reshape(-1, 2)
    measurements = np.asarray(measurements, dtype=float).reshape(-1, 7)
    order = np.argsort(pose_ids)
    pos = np.searchsorted(pose_ids[order], edge_ids)
    if np.any(pos >= len(pose_ids)) or np.any(pose_ids[order][np.minimum(pos, len(pose_ids) - 1)] != edge_ids):
        raise ValueError("edge_ids: an edge names a vertex not in pose_ids")
    index = order[pos]
    kappa, tau = se_sync_weights(information)
    return Problem(pose_ids, index[:, 0], index[:, 1], quaternion_to_rotation(measurements[:, 3:]),
                   measurements[:, :3].copy(), kappa, tau)


def problem_from_graph(graph):
    """(Problem, R (n, 3, 3), t (n, 3)) of a probslam.graph.PoseGraph3D's pose edges and values
    (its priors and landmarks are not part of SE-Sync's problem)."""
    edge_ids, measurements, information = graph.pose_edges()
    problem = problem_from_arrays(graph.pose_ids, edge_ids, measurements, information)
    poses = np.asarray(graph.poses)
    return problem, quaternion_to_rotation(poses[:, 3:]), poses[:, :3].copy()


def poses_rows(R, t):
    """(n, 7) pose rows [x, y, z, qx, qy, qz, qw] of rotations (n, 3, 3) and translations (n, 3)."""
    return np.hstack([np.asarray(t, dtype=float), rotation_to_quaternion(R)])


def residuals(p: Problem, R, t):
    """(rotation residuals (E, 3, 3) R_j - R_i R_ij, translation residuals (E, 3) t_j - t_i - R_i t_ij)."""
    Ri = R[p.i]
    return R[p.j] - Ri @ p.R, t[p.j] - t[p.i] - np.einsum("eab,eb->ea", Ri, p.t)


def objective(p: Problem, R, t) -> float:
    """SE-Sync's F of rotations R (n, 3, 3) and translations t (n, 3)."""
    rr, rt = residuals(p, R, t)
    return float(np.dot(p.kappa, np.einsum("eab,eab->e", rr, rr)) + np.dot(p.tau, np.einsum("ea,ea->e", rt, rt)))


def data_matrix(p: Problem) -> sp.csr_matrix:
    """M (4n x 4n), F = tr(X M X^T) with X = [t_1 .. t_n | R_1 .. R_n]: translation i is column i,
    R_i's columns are n + 3i .. n + 3i + 2."""
    n, E = p.n, len(p.i)
    ri = n + 3 * p.i[:, None] + np.arange(3)  # (E, 3) columns of R_i
    rj = n + 3 * p.j[:, None] + np.arange(3)
    # Translation term: tau a a^T, a nonzero on [i, j, R_i's three columns] = [-1, 1, -t_ij].
    idx = np.hstack([p.i[:, None], p.j[:, None], ri])  # (E, 5)
    a = np.hstack([-np.ones((E, 1)), np.ones((E, 1)), -p.t])
    rows = [np.repeat(idx, 5, axis=1).ravel()]
    cols = [np.tile(idx, (1, 5)).ravel()]
    vals = [(p.tau[:, None, None] * a[:, :, None] * a[:, None, :]).ravel()]
    # Rotation term: kappa B B^T with B = [I on R_j, -R_ij^T on R_i] (rows): blocks
    # (R_i, R_i) = R_ij R_ij^T = I, (R_j, R_j) = I, (R_i, R_j) = -R_ij, (R_j, R_i) = -R_ij^T.
    eye = np.broadcast_to(np.eye(3), (E, 3, 3))
    for r, c, block in ((ri, ri, eye), (rj, rj, eye), (ri, rj, -p.R), (rj, ri, -np.transpose(p.R, (0, 2, 1)))):
        rows.append(np.repeat(r, 3, axis=1).ravel())
        cols.append(np.tile(c, (1, 3)).ravel())
        vals.append((p.kappa[:, None, None] * block).ravel())
    N = 4 * n
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N))


def stacked(R, t):
    """X = [t_1 .. t_n | R_1 .. R_n] (3 x 4n)."""
    return np.hstack([np.asarray(t, dtype=float).T, np.transpose(R, (1, 0, 2)).reshape(3, -1)])


def _jacobian(p: Problem, R, t):
    """(J, r): the weighted residuals r (12E: per edge 9 rotation entries then 3 translation ones,
    times sqrt(kappa), sqrt(tau)) and their Jacobian (12E x 6n) in the perturbation
    R_i <- R_i Exp(w_i), t_i <- t_i + v_i, columns [v_i, w_i] of pose i at 6i."""
    E = len(p.i)
    rr, rt = residuals(p, R, t)
    sk, st = np.sqrt(p.kappa), np.sqrt(p.tau)
    r = np.hstack([sk[:, None] * rr.reshape(E, 9), st[:, None] * rt]).ravel()
    Ri, Rj = R[p.i], R[p.j]
    # d(R_j Exp(w)) = R_j G_k; d(-R_i Exp(w) R_ij) = -R_i G_k R_ij; d(-R_i Exp(w) t_ij) = -R_i G_k t_ij.
    d_rot_j = np.einsum("eac,kcb->eabk", Rj, _GENERATORS).reshape(E, 9, 3) * sk[:, None, None]
    d_rot_i = -np.einsum("eac,kcd,edb->eabk", Ri, _GENERATORS, p.R).reshape(E, 9, 3) * sk[:, None, None]
    d_tra_w = -np.einsum("eac,kcd,ed->eak", Ri, _GENERATORS, p.t) * st[:, None, None]
    base = 12 * np.arange(E)
    rows, cols, vals = [], [], []

    def add(row0, nrow, col0, block):
        rows.append(np.repeat((base[:, None] + row0 + np.arange(nrow))[:, :, None], 3, axis=2).ravel())
        cols.append(np.broadcast_to(col0[:, None, None] + np.arange(3), (E, nrow, 3)).ravel())
        vals.append(block.ravel())

    add(0, 9, 6 * p.j + 3, d_rot_j)
    add(0, 9, 6 * p.i + 3, d_rot_i)
    add(9, 3, 6 * p.j, np.broadcast_to(np.eye(3), (E, 3, 3)) * st[:, None, None])
    add(9, 3, 6 * p.i, -np.broadcast_to(np.eye(3), (E, 3, 3)) * st[:, None, None])
    add(9, 3, 6 * p.i + 3, d_tra_w)
    J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(12 * E, 6 * p.n))
    return J, r


def _retract(R, t, step):
    """Poses moved by step (6n) [v_i, w_i]: R_i Exp(w_i), t_i + v_i."""
    s = step.reshape(-1, 6)
    w = s[:, 3:]
    theta = np.linalg.norm(w, axis=1)
    K = np.einsum("nk,kab->nab", w, _GENERATORS)
    small = theta < 1e-8  # below it the series' next terms (theta^4) are under rounding
    th = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta ** 2 / 6, np.sin(th) / th)
    b = np.where(small, 0.5 - theta ** 2 / 24, (1 - np.cos(th)) / th ** 2)
    Exp = np.eye(3) + a[:, None, None] * K + b[:, None, None] * K @ K
    return R @ Exp, t + s[:, :3]


@dataclass
class Refinement:
    """``refine``'s result: rotations R (n, 3, 3) and translations t (n, 3) at the end, the
    objective F there and at the start, the Newton iterations and the gradient's norm."""
    R: np.ndarray
    t: np.ndarray
    objective: float
    initial_objective: float
    iterations: int
    gradient_norm: float  # ||grad F|| (Euclidean, in the [v, w] perturbation) at the result


def refine(p: Problem, R, t, max_iterations: int = 100, anchor: int = 0) -> Refinement:
    """Damped Newton on F from (R, t) with pose `anchor` held (F is invariant to a global rigid
    motion: the gauge). F is quadratic in X, so the second derivative of F(R_i Exp(w_i), t_i + v_i)
    at 0 is exact in closed form: 2 J^T J plus, on each w_i, 2 (Lambda_i - tr(Lambda_i) I) (from
    d^2 Exp(w) = [w]x^2 = w w^T - |w|^2 I against the gradient (X M)_{R_i}); Gauss-Newton alone
    (2 J^T J) converges only linearly where residuals are large (sphere2500: 60+ iterations). The
    damping (Marquardt's, on 2 J^T J's diagonal) grows until the damped matrix is positive definite
    (its inertia) and the step lowers F. Stops when an iteration lowers F by less than
    RELATIVE_DECREASE of it (or the model predicts less), or after max_iterations."""
    R = np.array(R, dtype=float)
    t = np.array(t, dtype=float)
    keep = np.ones(6 * p.n, dtype=bool)
    keep[6 * anchor:6 * anchor + 6] = False
    M = data_matrix(p)
    f0 = f = objective(p, R, t)
    lam = 0.0
    it = 0
    while it < max_iterations:
        it += 1
        J, r = _jacobian(p, R, t)
        H, g = _newton_system(p, R, t, M, J, r)
        H, g = H[keep][:, keep].tocsc(), g[keep]
        D = sp.diags(2 * np.asarray(J[:, keep].multiply(J[:, keep]).sum(axis=0)).ravel())
        accepted = False
        while lam <= LARGEST_DAMPING:
            lu = _symmetric_factor(H + lam * D)
            if np.count_nonzero(lu.U.diagonal() <= 0) == 0:
                dx = -lu.solve(g)
                predicted = -(g @ dx) - 0.5 * dx @ (H @ dx)  # the quadratic model's decrease of F
                if lam == 0.0 and predicted < RELATIVE_DECREASE * f:
                    break  # converged: the Newton step gains nothing above rounding
                step = np.zeros(6 * p.n)
                step[keep] = dx
                R_new, t_new = _retract(R, t, step)
                f_new = objective(p, R_new, t_new)
                if f_new <= f:
                    accepted = True
                    break
            lam = max(10.0 * lam, SMALLEST_DAMPING)
        if not accepted:  # converged, or no step lowers F: at a minimum to rounding
            break
        newton = lam == 0.0
        decrease = f - f_new
        R, t, f = R_new, t_new, f_new
        lam = lam / 100.0 if lam > SMALLEST_DAMPING else 0.0
        if newton and decrease < RELATIVE_DECREASE * f:  # a damped step's small gain is no sign of it
            break
    J, r = _jacobian(p, R, t)
    return Refinement(R, t, f, f0, it, float(np.linalg.norm(2.0 * (J.T @ r))))


def _newton_system(p: Problem, R, t, M, J, r):
    """(H, g): the exact second derivative and gradient of F(R_i Exp(w_i), t_i + v_i) at 0."""
    n = p.n
    Lam = multipliers(p, R, t, M)
    C = 2.0 * (Lam - np.trace(Lam, axis1=1, axis2=2)[:, None, None] * np.eye(3))
    cols = 6 * np.arange(n)[:, None, None] + 3 + np.arange(3)
    curvature = sp.csr_matrix((C.ravel(), (np.broadcast_to(np.swapaxes(cols, 1, 2), C.shape).ravel(),
                                           np.broadcast_to(cols, C.shape).ravel())), shape=(6 * n, 6 * n))
    return (2.0 * (J.T @ J) + curvature).tocsr(), 2.0 * (J.T @ r)


def multipliers(p: Problem, R, t, M=None):
    """Lambda_i = Sym(R_i^T (X M)_{R_i}) (n, 3, 3)."""
    if M is None:
        M = data_matrix(p)
    n = p.n
    XM = np.asarray((M @ stacked(R, t).T).T)  # M symmetric
    blocks = np.transpose(XM[:, n:].reshape(3, n, 3), (1, 0, 2))  # (n, 3, 3): (X M)_{R_i}
    G = np.einsum("nca,ncb->nab", R, blocks)
    return 0.5 * (G + np.transpose(G, (0, 2, 1)))


def certificate_matrix(p: Problem, R, t, M=None) -> sp.csr_matrix:
    """S = M - blkdiag(0_n, Lambda_1 .. Lambda_n), Lambda_i = Sym(R_i^T (X M)_{R_i})."""
    if M is None:
        M = data_matrix(p)
    n = p.n
    Lam = multipliers(p, R, t, M)
    r = n + 3 * np.arange(n)[:, None, None] + np.arange(3)[:, None]
    c = n + 3 * np.arange(n)[:, None, None] + np.arange(3)[None, :]
    L = sp.csr_matrix((Lam.ravel(), (np.broadcast_to(r, Lam.shape).ravel(), np.broadcast_to(c, Lam.shape).ravel())),
                      shape=M.shape)
    return (M - L).tocsr()


def _symmetric_factor(A):
    """SuperLU of A with diagonal pivots and a symmetric ordering: P A P^T = L U, U = D L^T, so
    the signs of U's diagonal are A's inertia. ValueError if SuperLU pivoted off the diagonal."""
    lu = spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    if not np.array_equal(lu.perm_r, lu.perm_c):
        raise ValueError("the factorisation pivoted off the diagonal: no inertia from it")
    return lu


def negative_eigenvalues(S, sigma: float) -> int:
    """The number of eigenvalues of symmetric S below sigma (Sylvester's law of inertia on an
    LDL^T-like factorisation of S - sigma I)."""
    lu = _symmetric_factor(S - sigma * sp.identity(S.shape[0], format="csr"))
    return int(np.count_nonzero(lu.U.diagonal() < 0))


def smallest_eigenvalues(S, k: int = 6, eta: float = None, return_vectors: bool = False):
    """The k smallest eigenvalues of symmetric sparse S, ascending (with return_vectors, and an
    orthonormal basis of the vectors' span): a shift sigma below lambda_min(S) found by inertia
    (-eta if nothing is below it, else bisection from Gershgorin's bound), then eigsh in
    shift-invert mode at sigma. The first is lambda_min to rounding; the others may skip a copy of
    a repeated eigenvalue (single-vector Lanczos), which the certificate's lambda_gap avoids."""
    N = S.shape[0]
    absrow = np.asarray(abs(S).sum(axis=1)).ravel()
    norm = float(absrow.max())
    if eta is None:
        eta = ETA_RELATIVE * norm
    sigma = -eta
    if negative_eigenvalues(S, sigma) > 0:
        diag = S.diagonal()
        lo = float(np.min(2 * diag - absrow)) - eta  # Gershgorin: no eigenvalue below it
        hi = sigma
        while hi - lo > BRACKET_RELATIVE * abs(lo):
            mid = 0.5 * (lo + hi)
            if negative_eigenvalues(S, mid) > 0:
                hi = mid
            else:
                lo = mid
        sigma = lo
    lu = _symmetric_factor(S - sigma * sp.identity(N, format="csr"))
    op = spla.LinearOperator((N, N), matvec=lu.solve, dtype=float)
    k = min(k, N - 1)
    v0 = np.random.default_rng(0).standard_normal(N)  # a fixed start: the same values run to run
    _, vectors = spla.eigsh(S, k=k, sigma=sigma, which="LM", OPinv=op, tol=1e-12, v0=v0)
    # Lanczos's own values are accurate relative to the largest 1 / (lambda - sigma) (the null
    # space's, ~1 / eta): the Rayleigh-Ritz values of S on the vectors' span are better past it.
    Q, _ = np.linalg.qr(vectors)
    values = np.linalg.eigvalsh(Q.T @ (S @ Q))
    return (values, Q) if return_vectors else values


def null_basis(R, t):
    """An orthonormal basis (4n x 4) of S's known null space at a critical point: X^T's three
    columns (the global rotation) and [1_n; 0] (the global translation)."""
    n = len(R)
    B = np.hstack([stacked(R, t).T, np.r_[np.ones(n), np.zeros(3 * n)][:, None]])
    return np.linalg.qr(B)[0]


@dataclass
class Certificate:
    """``certify``'s verdict on a critical point: S's smallest eigenvalues, the tolerance and
    whether S is positive semidefinite within it (then the point is a global minimum)."""
    lambda_min: float      # smallest eigenvalue of S (about 0 when certified: S has a null space)
    lambda_gap: float      # smallest eigenvalue of S off its known null space (X^T, the translation)
    eta: float             # the tolerance: certified when lambda_min >= -eta
    norm: float            # ||S||_inf, eta's scale
    certified: bool
    stationarity: float    # ||S X^T||_F / (||S||_inf ||X||_F): how far from a critical point


def certify(p: Problem, R, t, eta_relative: float = ETA_RELATIVE) -> Certificate:
    """The certificate of poses (R, t), which should be a critical point of F (refine first)."""
    M = data_matrix(p)
    S = certificate_matrix(p, R, t, M)
    norm = float(np.asarray(abs(S).sum(axis=1)).max())
    eta = eta_relative * norm
    X = stacked(R, t)
    stationarity = float(np.linalg.norm(S @ X.T) / (norm * np.linalg.norm(X)))
    certified = negative_eigenvalues(S, -eta) == 0
    values, Q = smallest_eigenvalues(S, k=10, eta=eta, return_vectors=True)
    # lambda_gap: Rayleigh-Ritz of S on the Lanczos span with the known null space projected out
    # (so a copy of the null eigenvalue the Lanczos run skipped cannot stand in for it). It is
    # a margin, good to ~1e-6 relative: the solves with S + eta I (condition ~1 / ETA_RELATIVE)
    # carry that error into the directions past the null space. lambda_min and the verdict are
    # exact to rounding.
    Nb = null_basis(R, t)
    P = Q - Nb @ (Nb.T @ Q)
    U, sv, _ = np.linalg.svd(P, full_matrices=False)
    U = U[:, sv > 1e-8]
    gap = float(np.linalg.eigvalsh(U.T @ (S @ U))[0]) if U.shape[1] else float("nan")
    return Certificate(float(values[0]), gap, eta, norm, bool(certified), stationarity)


__all__ = ["Certificate", "Problem", "Refinement", "certificate_matrix", "certify", "data_matrix",
           "multipliers", "negative_eigenvalues", "null_basis", "objective", "poses_rows",
           "problem_from_arrays", "problem_from_graph", "quaternion_to_rotation", "refine", "residuals",
           "rotation_to_quaternion", "se_sync_weights", "smallest_eigenvalues", "stacked"]
