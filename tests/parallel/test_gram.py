"""The batched Gram products equal the point-wise sparse triple products.

Collective: one rank under pytest, two under `mpiexec -n 2`.
"""
import numpy as np
import pytest
import scipy.sparse as sp
from petsc4py import PETSc

from pfmembrane.kernels import nodes
from pfmembrane.parallel.discretization import Discretization


@pytest.fixture(scope='module', params=[1, 4])
def grid(request):
    box = (1.0, 1.4)
    xy = nodes.uniform(box, 600)
    xy[:, 0] = box[0] * (xy[:, 0] / box[0]) ** 1.5  # graded: supports of many sizes
    return Discretization(PETSc.COMM_WORLD, xy, box, gamma=0.8, cutoff=1e-6, degree=request.param)


def test_gram_equals_sparse_triple_products(grid):
    o, g = grid.ops, grid.gram
    rng = np.random.default_rng(3)
    n = len(o.w)
    a, b, s, t = (rng.standard_normal(n) for _ in range(4))
    upper = g.upper_data([({'BL': 0.3, 'B0': a}, s), ({'B0': 1.0}, t)])
    D = 0.3 * o.BL + sp.diags(a) @ o.B0
    ref = (D.T @ sp.diags(s) @ D + o.B0.T @ sp.diags(t) @ o.B0).tocsr()
    H = g.full(upper)
    assert H.shape == ref.shape
    assert abs(H - ref).max() <= 1e-13 * abs(ref).max()
    # the exact pattern of the point-wise products, not the per-triangle unions
    assert H.nnz == grid.hessian_pattern().nnz
    assert abs(H - H.T).max() == 0.0


def test_blocks_on_demand_give_the_same_products(grid):
    o, g = grid.ops, grid.gram
    w = o.w
    K = g.full(g.upper_data([({'Br': 1.0}, w), ({'Bz': 1.0}, w)],
                            blocks={'Br': g.block('Br'), 'Bz': g.block('Bz')}))
    ref = (o.Br.T @ sp.diags(w) @ o.Br + o.Bz.T @ sp.diags(w) @ o.Bz).tocsr()
    assert abs(K - ref).max() <= 1e-13 * abs(ref).max()
