"""Local maximum-entropy (max-ent) approximants in two dimensions.

At a point x with nodes x_a, y_a = x - x_a and per-node locality beta_a,

    p_a(x) = exp(f_a) / Z,   f_a = -beta_a |y_a|^2 + lam . y_a,
    Z = sum_a exp(f_a),

where lam*(x) minimises log Z, i.e. solves r = sum_a p_a y_a = 0 (linear
reproduction). First and second derivatives follow from implicit
differentiation of r(x, lam*(x)) = 0 and account for beta_a varying between
nodes.

Only nodes with exp(-beta_a |y_a|^2) >= cutoff enter the sums. Since lam is
solved on the truncated set, the truncated approximant still satisfies
partition of unity and linear reproduction exactly. Dropping the Gaussian
tail perturbs the values p_a by about `cutoff` for gamma = beta h^2 <= 1
(largest change 0.5-1.5 cutoff). The discarded weights carry the factor
exp(lam . y_a), so the perturbation grows with gamma: about 3 cutoff at
gamma = 2, 10-40 cutoff at gamma = 4 and 1e2-1e3 cutoff at gamma = 6 on
quasi-uniform nodes, and more on strongly graded ones.

On the boundary of the hull the weights of the nodes off a boundary edge
vanish like dist**alpha_a with alpha_a >= 1 (alpha_a > 1 unless these nodes
lie at equal distance from the edge), so the approximant is in general only
continuous there. Derivatives at points exactly on the boundary satisfy the
derivative identities but need not match one-sided difference quotients, and
second derivatives there are inaccurate; at a distance d inside the hull the
rounding error of the second derivatives grows like 1e-16 h / d.
"""

import itertools
from typing import NamedTuple, Optional

import numpy as np
import scipy.sparse
from scipy.spatial import ConvexHull, cKDTree

_MAXITER = 100        # Newton iterations; boundary points need about 30
_MAXHALVINGS = 60     # step halvings in the line search
_ARMIJO = 1e-4        # sufficient-decrease constant of the line search
_NODE_BLOCK = 1000    # nodes per neighbour query


class Basis(NamedTuple):
    """Max-ent basis functions at evaluation points, in CSR layout.

    Attributes
    ----------
    indptr : ndarray, shape (npts + 1,)
        Row pointer; the entries of point i are ``indptr[i]:indptr[i + 1]``.
    indices : ndarray, shape (nnz,)
        Node indices, sorted within each point.
    p : ndarray, shape (nnz,)
        Values p_a(x).
    dp : ndarray, shape (nnz, 2), or None
        First derivatives (d/dr, d/dz).
    ddp : ndarray, shape (nnz, 3), or None
        Second derivatives (d2/dr2, d2/drdz, d2/dz2).
    """

    indptr: np.ndarray
    indices: np.ndarray
    p: np.ndarray
    dp: Optional[np.ndarray]
    ddp: Optional[np.ndarray]


def support_radius(beta, cutoff=1e-6):
    """Radius beyond which a node's Gaussian prior drops below `cutoff`.

    Parameters
    ----------
    beta : array_like
        Locality parameters beta_a.
    cutoff : float
        Prior weight exp(-beta_a |y|^2) below which a node is discarded.

    Returns
    -------
    ndarray
        R_a = sqrt(-ln(cutoff) / beta_a).
    """
    return np.sqrt(-np.log(cutoff) / np.asarray(beta, dtype=float))


def local_maxent(points, nodes, beta, cutoff=1e-6, derivatives=2, tol=1e-12,
                 chunk=5000):
    """Evaluate local max-ent basis functions and their derivatives.

    Parameters
    ----------
    points : array_like, shape (npts, 2)
        Evaluation points in the convex hull of `nodes` (the hull boundary
        included); they may coincide with nodes.
    nodes : array_like, shape (nnodes, 2)
        Node coordinates.
    beta : array_like, shape (nnodes,)
        Locality parameters, typically gamma / h_a**2.
    cutoff : float
        Node a is used at x only if exp(-beta_a |x - x_a|^2) >= cutoff.
        Partition of unity and linear reproduction remain exact; the values
        change by about `cutoff` for gamma <= 1 and by more for larger gamma
        (see the module docstring).
    derivatives : {0, 1, 2}
        Highest derivative order to compute.
    tol : float
        Newton tolerance on |sum_a p_a y_a|, relative to the local length
        scale 1 / sqrt(max_a beta_a).
    chunk : int
        Number of points processed at once; bounds the working memory (about
        17 kB per point with 60 neighbours). Smaller chunks are not slower.

    Returns
    -------
    Basis

    Raises
    ------
    ValueError
        If a point has no neighbours or lies outside the convex hull of the
        nodes.
    RuntimeError
        If Newton's method fails at a point inside the hull.
    """
    points = np.ascontiguousarray(points, dtype=float)
    nodes = np.ascontiguousarray(nodes, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or nodes.ndim != 2 \
            or nodes.shape[1] != 2:
        raise ValueError("points and nodes must have shape (n, 2)")
    if derivatives not in (0, 1, 2):
        raise ValueError("derivatives must be 0, 1 or 2")
    beta = np.broadcast_to(np.asarray(beta, dtype=float), len(nodes))
    indptr, indices = _neighbours(points, nodes, support_radius(beta, cutoff))

    fields = [np.empty((len(indices),) + shape)
              for shape in [(), (2,), (3,)][:derivatives + 1]]
    for start in range(0, len(points), chunk):
        stop = min(start + chunk, len(points))
        entries = slice(indptr[start], indptr[stop])
        _evaluate(points, start, stop, nodes, beta,
                  indptr[start:stop + 1] - indptr[start], indices[entries],
                  tol, [field[entries] for field in fields])
    return Basis(indptr, indices, *fields, *[None] * (2 - derivatives))


def interpolate(basis, values):
    """Evaluate sum_a p_a(x) values_a at every point of `basis`.

    Parameters
    ----------
    basis : Basis
    values : array_like, shape (nnodes,) or (nnodes, k)
        Nodal values.

    Returns
    -------
    ndarray, shape (npts,) or (npts, k)
    """
    values = np.asarray(values)
    matrix = scipy.sparse.csr_matrix(
        (basis.p, basis.indices, basis.indptr),
        shape=(len(basis.indptr) - 1, values.shape[0]))
    return matrix @ values


def _neighbours(points, nodes, radius):
    """CSR pattern (by point, nodes sorted) of the nodes covering points."""
    # The tree is on the points so that each node can use its own radius.
    # Nodes are queried in blocks to bound the memory of the Python lists.
    tree = cKDTree(points)
    point, node = [], []
    for start in range(0, len(nodes), _NODE_BLOCK):
        block = slice(start, start + _NODE_BLOCK)
        hits = tree.query_ball_point(nodes[block], radius[block],
                                     return_sorted=False)
        counts = np.fromiter(map(len, hits), dtype=np.int64, count=len(hits))
        point.append(np.fromiter(itertools.chain.from_iterable(hits),
                                 dtype=np.int64, count=counts.sum()))
        node.append(np.repeat(np.arange(start, start + len(hits)), counts))
    point = np.concatenate(point)
    # COO to CSR conversion is a linear-time sort by point; it leaves the
    # nodes sorted within each point.
    pattern = scipy.sparse.csr_matrix(
        (np.ones(len(point), dtype=np.int8), (point, np.concatenate(node))),
        shape=(len(points), len(nodes)))
    per_point = np.diff(pattern.indptr)
    if np.any(per_point == 0):
        bad = points[np.argmin(per_point)]
        raise ValueError(f"point {bad} has no neighbouring nodes")
    return pattern.indptr.astype(np.int64), pattern.indices.astype(np.int64)


def _evaluate(points, start, stop, nodes, beta, indptr, indices, tol, fields):
    """Fill `fields` (values, then derivatives) at points[start:stop].

    The fields are flat arrays in CSR order. The work is done on arrays
    padded to (npts, m), m the largest number of neighbours, with coordinate
    components first: y[i, c, a] is component i of y_a at point c. Padding
    entries have y = 0 and beta = 0, and are excluded from the sums by a zero
    prior weight.
    """
    counts = np.diff(indptr)
    mask = np.arange(counts.max()) < counts[:, None]
    row = np.repeat(np.arange(start, stop), counts)

    def pad(values):
        padded = np.zeros(mask.shape)
        padded[mask] = values
        return padded

    # Component-wise gathers are much faster than on (n, 2) arrays.
    y = np.array([pad(points[row, i] - nodes[indices, i]) for i in range(2)])
    b = pad(beta[indices])

    p, failed, residual = _solve(y, b, mask, tol)
    if np.any(failed):
        _raise_failure(points, nodes, start + np.flatnonzero(failed),
                       residual[failed])
    fields[0][:] = p[mask]
    if len(fields) > 1:
        q, hessian = _derivatives(y, b, p, second=len(fields) > 2)
        for field, components in zip(fields[1:], (p * q, hessian)):
            for k, component in enumerate(components):
                field[:, k] = component[mask]


def _dot(y, v):
    """y_a . v per point, for y of shape (2, n, m) and v of shape (2, n)."""
    return y[0] * v[0][:, None] + y[1] * v[1][:, None]


def _inv2(a):
    """Inverse and determinant of 2x2 matrices stored as a[i, j, ...]."""
    det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.array([[a[1, 1], -a[0, 1]], [-a[1, 0], a[0, 0]]]) / det
    return inv, det


def _log_change(p, u):
    """log(sum_a p_a exp(u_a)) per point, accurate also for tiny u.

    This is the change of log Z along a step. Forming it directly, rather
    than as a difference of two values of log Z, keeps it accurate near
    convergence, where the decrease is far below the rounding error of log Z.
    """
    umax = u.max(axis=1)
    small = np.maximum(umax, -u.min(axis=1)) <= 0.5
    change = np.empty(len(u))
    change[small] = np.log1p(np.sum(p[small] * np.expm1(u[small]), axis=1))
    big = ~small
    with np.errstate(divide="ignore"):
        change[big] = umax[big] + np.log(np.sum(
            p[big] * np.exp(u[big] - umax[big, None]), axis=1))
    return change


def _solve(y, b, mask, tol):
    """Damped Newton for lam* = argmin log Z on padded arrays.

    Convergence is |r| <= tol * ell with ell = 1 / sqrt(max_a beta_a). Each
    Newton step is backtracked until log Z decreases sufficiently (Armijo),
    which makes the iteration globally convergent on this convex problem,
    including points on or next to the boundary of the hull where lam* is
    large and J nearly singular.

    Returns
    -------
    p : ndarray, shape (n, m)
        Converged values p_a.
    failed : ndarray of bool, shape (n,)
        Points where Newton's method did not converge.
    residual : ndarray, shape (n,)
        Final |r| / ell.
    """
    npts = y.shape[1]
    prior = np.where(mask, -b * (y[0] ** 2 + y[1] ** 2), -np.inf)
    ell = 1.0 / np.sqrt(b.max(axis=1))
    lam = np.zeros((2, npts))
    p_final = np.zeros(mask.shape)
    residual = np.full(npts, np.inf)
    failed = np.zeros(npts, dtype=bool)
    active = np.arange(npts)
    stuck = np.zeros(npts, dtype=bool)

    # A diverging lam (point outside the hull of its neighbours) produces
    # non-finite values; they fail the checks below and are reported.
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(_MAXITER):
            f = prior + _dot(y, lam)
            p = np.exp(f - f.max(axis=1, keepdims=True))
            p /= p.sum(axis=1, keepdims=True)
            r = np.einsum("cm,icm->ic", p, y)
            residual[active] = np.hypot(*r) / ell
            done = residual[active] <= tol
            p_final[active[done]] = p[done]
            failed[active[stuck]] = True
            keep = ~(done | stuck)
            if not keep.all():
                # Work only on the points still iterating.
                active, y, prior, ell, lam, p, r = (
                    active[keep], y[:, keep], prior[keep], ell[keep],
                    lam[:, keep], p[keep], r[:, keep])
            if active.size == 0:
                break

            # J = covariance of y under p, centred for accuracy far from r = 0.
            yc = y - r[:, :, None]
            jac = np.einsum("icm,jcm->ijc", p * yc, yc)
            inv, det = _inv2(jac)
            step = -np.einsum("ijc,jc->ic", inv, r)
            slope = np.sum(r * step, axis=0)
            ok = (det > 0) & np.isfinite(step).all(axis=0) & (slope < 0)

            # Backtracking line search; t * u_a is the change of f_a.
            u = _dot(y, step)
            t = np.ones(active.size)
            pending = np.flatnonzero(ok)
            for _ in range(_MAXHALVINGS):
                if pending.size == 0:
                    break
                change = _log_change(p[pending], t[pending, None] * u[pending])
                accept = change <= _ARMIJO * t[pending] * slope[pending]
                pending = pending[~accept]
                t[pending] *= 0.5
            ok[pending] = False
            lam[:, ok] += t[ok] * step[:, ok]
            stuck = ~ok
    failed[active] = True
    return p_final, failed, residual


def _raise_failure(points, nodes, failed, residual):
    """Raise for the points `failed` where Newton's method did not converge.

    `residual` holds their final relative residuals.
    """
    hull = ConvexHull(nodes)
    scale = np.ptp(nodes, axis=0).max()
    excess = (points[failed] @ hull.equations[:, :2].T
              + hull.equations[:, 2]).max(axis=1)
    outside = failed[excess > 1e-12 * scale]
    if outside.size:
        raise ValueError(f"{outside.size} point(s) outside the convex hull of "
                         f"the nodes, e.g. {points[outside[0]]}")
    residual = np.nan_to_num(residual, nan=np.inf)
    worst = np.argmax(residual)
    raise RuntimeError(
        f"max-ent Newton iteration failed at {failed.size} point(s); the "
        f"worst is point {failed[worst]} at {points[failed[worst]]} with "
        f"relative residual {residual[worst]:.3g}. If the nodes within the "
        f"cut-off radius do not surround a point, use a smaller cutoff or "
        f"gamma.")


def _derivatives(y, b, p, second):
    """q_a = grad p_a / p_a and, if requested, the Hessians of p_a.

    Newton leaves a residual r = sum_b p_b y_b of order tol. The formulas
    below differentiate the family r(x, lam(x)) = r (constant), which is the
    approximant to that accuracy and satisfies the derivative identities
    exactly. This matters next to the hull boundary, where Dlam ~ 1/dist and
    the residual would otherwise spoil the derivatives. With the centred
    yt_b = y_b - r (so that d yt_b / dx = I), s = sum_b p_b beta_b y_b,
    J = sum_b p_b yt_b yt_b^T, K = I - 2 sum_b p_b beta_b yt_b y_b^T and
    Dlam = d lam / dx = -J^{-1} K:

        q_a = -2 beta_a y_a + 2 s + Dlam^T yt_a,
        Hess p_a = p_a (q_a q_a^T + grad q_a),
        grad q_a[i, j] = -2 beta_a delta_ij + 2 grad s[i, j] + Dlam[j, i]
                         + sum_k yt_ak dDlam[k, i] / dx_j,
        grad s[i, j] = sum_b p_b beta_b y_bi q_bj + delta_ij sum_b p_b beta_b,
        dJ / dx_j = sum_b p_b q_bj yt_b yt_b^T,
        dK / dx_j = -2 sum_b p_b beta_b (q_bj yt_b y_b^T + e_j y_b^T
                                         + yt_b e_j^T),
        dDlam / dx_j = J^{-1} (dJ / dx_j) J^{-1} K - J^{-1} dK / dx_j.

    For r = 0 these reduce to the textbook expressions with per-node beta.

    Returns q with shape (2, n, m) and, if `second`, the Hessians with shape
    (3, n, m) ordered (rr, rz, zz), else None.
    """
    eye = np.eye(2)[:, :, None]
    pb = p * b
    r = np.einsum("cm,icm->ic", p, y)
    yt = y - r[:, :, None]
    yt_yt = yt[:, None] * yt[None]                 # [k, l] = yt_k yt_l
    yt_y = yt[:, None] * y[None]                   # [k, l] = yt_k y_l
    s = np.einsum("cm,icm->ic", pb, y)
    jac = np.einsum("cm,klcm->klc", p, yt_yt)
    k_mat = eye - 2.0 * np.einsum("cm,klcm->klc", pb, yt_y)
    inv, _ = _inv2(jac)
    dlam = -np.einsum("ikc,kjc->ijc", inv, k_mat)
    q = (-2.0 * b * y + 2.0 * s[:, :, None]
         + np.einsum("kic,kcm->icm", dlam, yt))
    if not second:
        return q, None

    pq = p * q
    pbq = b * pq
    grad_s = np.einsum("icm,jcm->ijc", y, pbq) + eye * pb.sum(axis=1)
    s_t = s - r * pb.sum(axis=1)                   # sum_b p_b beta_b yt_b
    # Index order [k, l, j, c] for d(matrix)[k, l] / dx_j.
    d_jac = np.einsum("klcm,jcm->kljc", yt_yt, pq)
    d_k = -2.0 * (np.einsum("klcm,jcm->kljc", yt_y, pbq)
                  + eye[:, None] * s[None, :, None]      # delta_kj s_l
                  + s_t[:, None, None] * eye[None])      # s_t_k delta_lj
    # dDlam/dx_j = -J^{-1} (dJ_j Dlam + dK_j), using J^{-1} K = -Dlam.
    inner = np.einsum("kljc,lic->kijc", d_jac, dlam) + d_k
    d_dlam = -np.einsum("mkc,kijc->mijc", inv, inner)
    # Per-point part of grad q; both parts symmetrised as Hess p_a is.
    base = 2.0 * grad_s + dlam.transpose(1, 0, 2)
    base = 0.5 * (base + base.transpose(1, 0, 2))
    d_dlam = 0.5 * (d_dlam + d_dlam.transpose(0, 2, 1, 3))
    hessian = np.empty((3,) + p.shape)
    for n, (i, j) in enumerate(((0, 0), (0, 1), (1, 1))):
        grad_q = (base[i, j][:, None] + yt[0] * d_dlam[0, i, j][:, None]
                  + yt[1] * d_dlam[1, i, j][:, None])
        if i == j:
            grad_q -= 2.0 * b
        hessian[n] = p * (q[i] * q[j] + grad_q)
    return q, hessian
