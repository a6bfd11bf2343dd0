"""reproduction.py: quadratic reproduction and finite-difference derivatives of the
corrected basis (quadratic.patch) against max-ent, on graded, perturbed nodes of the
unit square; then its Lebesgue constant approaching the edge z = 0."""
import numpy as np
from pfmembrane.kernels import maxent
from pfmembrane.kernels.nodes import nodal_spacing
rng = np.random.default_rng(0)
g = np.linspace(0, 1, 21)
nodes = np.column_stack([a.ravel() for a in np.meshgrid(g, g)])
nodes[:, 0] **= 1.7                                   # graded in r
inner = ((nodes > 0) & (nodes < 1)).all(axis=1)
nodes[inner] += 0.01 * rng.standard_normal((inner.sum(), 2))
beta = 0.4 / nodal_spacing(nodes) ** 2
pts = 0.05 + 0.9 * rng.random((200, 2))
x, z = pts.T
for order in (1, 2):
    maxent.ORDER = order
    B = maxent.local_maxent(pts, nodes, beta, 1e-6, 2)
    rows = np.repeat(np.arange(len(pts)), np.diff(B.indptr))
    S = lambda v: np.bincount(rows, v, minlength=len(pts))
    xa = nodes[B.indices]
    f = xa[:, 0] ** 2 + 3 * xa[:, 0] * xa[:, 1] - xa[:, 1] ** 2
    print(order, 'value', abs(S(B.p * f) - (x ** 2 + 3 * x * z - z ** 2)).max(),
          'gradient', abs(S(B.dp[:, 0] * f) - (2 * x + 3 * z)).max(),
          'laplacian', abs(S((B.ddp[:, 0] + B.ddp[:, 2]) * f)).max(),
          'lebesgue', S(abs(B.p)).max(), 'min p', B.p.min())
    e = 1e-6
    for d in (0, 1):
        shift = np.eye(2)[d] * e
        Bp, Bm = (maxent.local_maxent(pts + s, nodes, beta, 1e-6, 2) for s in (shift, -shift))
        fd, fdd = (Bp.p - Bm.p) / (2 * e), (Bp.dp - Bm.dp) / (2 * e)
        print('  d/d', 'rz'[d], 'gradient', abs(fd - B.dp[:, d]).max() / abs(B.dp).max(),
              'hessian', abs(fdd - B.ddp[:, [d, d + 1]]).max() / abs(B.ddp).max())
maxent.ORDER = 2
for d in (1e-4, 1e-3, 1e-2, 3e-2):
    p = np.column_stack([0.2 + 0.6 * rng.random(50), np.full(50, d)])
    B = maxent.local_maxent(p, nodes, beta, 1e-6, 2)
    rows = np.repeat(np.arange(len(p)), np.diff(B.indptr))
    print('z', d, 'lebesgue', np.bincount(rows, abs(B.p)).max(), 'max |ddp|', abs(B.ddp).max())
