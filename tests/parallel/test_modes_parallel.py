"""The mode analysis (pfmembrane.parallel.stability) on COMM_WORLD agrees with one rank:
the same index, eigenvalues and modes for m = 0 ... 3.

Under `mpiexec -n 2` only (skipped on one rank).
"""
import numpy as np
import pytest
from petsc4py import PETSc

import pfmembrane as pf
from pfmembrane.parallel.problem import Problem

pytestmark = pytest.mark.slow

SCENE = pf.Scene(reduced_volume=0.8, branch='oblate')
EPS = 0.06


def _spectra(grid, result):
    problem = Problem(grid, SCENE, EPS, 'modes_test_')
    a = problem.modes(result.phi, result.nu[0])
    try:
        spectra = [a.spectrum(m) for m in range(4)]
        modes = [grid.discrete.layout.nodal(s.vectors[0], 0.0) for s in spectra]
    finally:
        problem.close()
    return spectra, modes


def test_index_eigenvalues_and_modes_agree_with_one_rank(distributed):
    world = pf.Grid.uniform(SCENE, nodes=1500)
    result = pf.solve(SCENE, world, eps=EPS, checks=False)
    assert result.converged
    many, many_modes = _spectra(world, result)
    one, one_modes = _spectra(pf.Grid.uniform(SCENE, nodes=1500, comm=PETSc.COMM_SELF), result)
    assert [s.index for s in many] == [s.index for s in one]
    assert sum(s.index for s in many) > 0    # an index that can differ: m = 2 is unstable
    for s, t, u, v in zip(many, one, many_modes, one_modes):
        np.testing.assert_allclose(s.eigenvalues, t.eigenvalues, rtol=1e-7, atol=1e-9)
        assert min(np.abs(u - v).max(), np.abs(u + v).max()) < 1e-5 * np.abs(u).max()
