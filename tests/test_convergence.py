"""Convergence in the nodal spacing at fixed eps: the discocyte's energy on
four uniform half-box grids, each solved from the last one's solution
transferred to its nodes. The differences of successive energies fall as
h^p; the fitted p is about 3.4 (runs/method/notes.md)."""
import sys

import numpy as np
import pytest

import pfmembrane as pf

pytestmark = pytest.mark.slow
EPS = 0.08


@pytest.fixture(scope='module')
def refinement():
    PETSc = pf.api.petsc(sys.argv[:1])
    scene = pf.Scene(symmetric=True)
    rows, start = [], None
    for nodes in (1500, 3000, 6000, 12000):
        grid = pf.Grid.uniform(scene, nodes=nodes, comm=PETSc.COMM_SELF)
        res = pf.solve(scene, grid, eps=EPS, start=start, checks=False,
                       options={'pf_stage1': 'none'} if start else None)
        assert res.converged
        rows.append((np.mean(grid.discrete.h), res.energy))
        start = res
    return np.array(rows)


def test_the_energy_falls_monotonically_as_h_falls(refinement):
    assert np.all(np.diff(refinement[:, 1]) < 0)


def test_the_energy_converges_at_the_fitted_rate(refinement):
    h, energy = refinement.T
    differences = -np.diff(energy)
    p = np.polyfit(np.log(h[1:]), np.log(differences), 1)[0]
    assert 2.8 < p < 4.0, p
    # Richardson with the fitted rate: the finest grid lies a few 1e-5 above the limit
    limit = energy[-1] - differences[-1] / ((h[-2] / h[-1]) ** p - 1)
    assert 0 < energy[-1] - limit < 5e-5
