"""The half box with a mirror plane against the full box, without a solve.

Collective: runs on one rank under pytest and on two under `mpiexec -n 2`.
"""
import numpy as np
import pytest
from petsc4py import PETSc

from pfmembrane.kernels import nodes
from pfmembrane.parallel.assembly import Assembly
from pfmembrane.parallel.discretization import Discretization
from pfmembrane.kernels.initial import spheroid_axes, spheroid_phi

BOX, R, EPS, N = (1.5, 2.0), 0.4, 0.08, 1100
A0, V0 = 4 * np.pi * R ** 2, 0.8 * 4 / 3 * np.pi * R ** 3


def functionals(half, branch):
    xy = nodes.uniform(BOX, N, half=half)
    plane = BOX[1] / 2 if half else None
    grid = Discretization(PETSc.COMM_WORLD, xy, BOX, plane=plane)
    P = Assembly(grid, EPS, 1.0, 0.0, (A0, V0), BOX[1] / 2)
    x = P.create_vec()
    lay = grid.layout
    a, c = spheroid_axes(A0, V0, branch)
    x.setArray(spheroid_phi(xy[lay.order[lay.start:lay.start + lay.nowned]], a, c,
                            BOX[1] / 2, EPS))
    return grid, P.values(x)


def test_the_half_lattice_is_the_upper_half_of_the_full_one():
    full, half = nodes.uniform(BOX, N), nodes.uniform(BOX, N, half=True)
    upper = full[full[:, 1] >= BOX[1] / 2]
    key = lambda x: x[np.lexsort(x.T)]  # noqa: E731
    assert np.array_equal(key(upper), key(half))
    assert np.any(np.all(half == [0.0, BOX[1] / 2], axis=1))  # the corner on the axis


@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_half_box_integrals_equal_the_full_box_ones(branch):
    full_grid, full = functionals(False, branch)
    half_grid, half = functionals(True, branch)
    assert half_grid.nquad * 2 == full_grid.nquad
    # Same lattice, same basis on the upper half: E, A, V agree to rounding.
    np.testing.assert_allclose(half[:3], full[:3], rtol=1e-11)
    assert abs(full[3]) < 1e-12 and half[3] == 0.0  # the moment of an even field
