"""Finite-difference checks of the distributed gradients and Hessians.

Collective: runs on one rank under pytest and on two under `mpiexec -n 2`.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from pfmembrane.kernels import nodes
from pfmembrane.parallel.assembly import Assembly
from pfmembrane.parallel.discretization import Discretization
from pfmembrane.kernels.initial import spheroid_axes, spheroid_phi

BOX, R, EPS = (1.0, 1.4), 0.4, 0.12


@pytest.fixture(scope='module', params=[(0.0, False), (1.5, False), (0.0, True)],
                ids=['c0=0', 'c0=1.5', 'half box'])
def problem(request):
    c0, half = request.param
    comm = PETSc.COMM_WORLD
    xy = nodes.uniform(BOX, 700, half=half)
    # Graded spacing: the derivatives must hold with a per-node beta_a.
    xy[:, 0] = BOX[0] * (xy[:, 0] / BOX[0]) ** 1.3
    plane = BOX[1] / 2 if half else None
    grid = Discretization(comm, xy, BOX, gamma=0.8, cutoff=1e-6, degree=4, plane=plane)
    A0, V0 = 4 * np.pi * R ** 2, 0.8 * 4 / 3 * np.pi * R ** 3
    P = Assembly(grid, EPS, 1.0, c0, (A0, V0), BOX[1] / 2)
    x = P.create_vec()
    lay = grid.layout
    own = lay.order[lay.start:lay.start + lay.nowned]
    a, c = spheroid_axes(A0, V0, 'oblate')
    x.setArray(spheroid_phi(xy[own], a, c, BOX[1] / 2, EPS))
    return P, x


def _direction(P, x, seed):
    d = x.duplicate()
    rng = np.random.default_rng(seed)
    full = rng.standard_normal(P.layout.nglobal)
    d.setArray(full[P.layout.start:P.layout.start + P.layout.nowned])
    return d


def test_gradients_match_finite_differences(problem):
    P, x = problem
    gE, gA = P.create_vec(), P.create_vec()
    P.gradients(x, gE, gA)
    grads = [gE, *P.constraint_gradients(gA)]
    d = _direction(P, x, 1)
    t = 1e-5
    xp, xm = x.duplicate(), x.duplicate()
    x.copy(xp); xp.axpy(t, d)
    x.copy(xm); xm.axpy(-t, d)
    fd = (P.values(xp) - P.values(xm)) / (2 * t)
    for i, g in enumerate(grads):
        exact = g.dot(d)
        assert abs(fd[i] - exact) <= 1e-6 * max(abs(exact), 1e-3 * g.norm() * d.norm()), (i, fd[i], exact)


@pytest.mark.parametrize('sigma', [0.0, 7.5])
def test_hessian_matches_finite_differences(problem, sigma):
    P, x = problem
    gE, gA = P.create_vec(), P.create_vec()
    P.gradients(x, gE, gA)
    C = P.constraint_gradients(gA)
    K = P.assemble_bordered(x, sigma, C, 0.0)
    d = _direction(P, x, 2)
    X, Y = K.createVecs()
    nl = P.layout.nowned
    X.getArray()[:nl] = d.getArray(readonly=True)
    K.mult(X, Y)
    Hd = Y.getArray(readonly=True)[:nl]
    t = 1e-6
    gp, gm, ap, am = (x.duplicate() for _ in range(4))
    xp = x.duplicate(); x.copy(xp); xp.axpy(t, d)
    P.gradients(xp, gp, ap)
    x.copy(xp); xp.axpy(-t, d)
    P.gradients(xp, gm, am)
    fd = (gp.getArray() - gm.getArray() - sigma * (ap.getArray() - am.getArray())) / (2 * t)
    mpi = PETSc.COMM_WORLD.tompi4py()
    scale = mpi.allreduce(np.abs(fd).max(), op=MPI.MAX)
    err = mpi.allreduce(np.abs(fd - Hd).max(), op=MPI.MAX)
    assert err < 1e-6 * scale, (err, scale)
    # Border blocks: K [0; e_j] = -C_j (the constraint gradients).
    X.zeroEntries()
    if PETSc.COMM_WORLD.getRank() == PETSc.COMM_WORLD.getSize() - 1:
        X.getArray()[nl] = 1.0
    K.mult(X, Y)
    assert np.allclose(Y.getArray()[:nl], -C[0].getArray())
