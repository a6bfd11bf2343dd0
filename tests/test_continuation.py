"""The tangent of a branch (pf.tangent, Solver.tangent) against central differences of
converged solves, in the reduced volume and in the spontaneous curvature."""
import sys

import numpy as np
import pytest

import pfmembrane as pf

pytestmark = pytest.mark.slow

EPS = 0.06


@pytest.fixture(scope='module')
def solved():
    comm = pf.api.petsc(sys.argv[:1]).COMM_SELF
    scene = pf.Scene(reduced_volume=0.9, branch='oblate')
    result = pf.solve(scene, pf.Grid.uniform(scene, nodes=1500, comm=comm), eps=EPS, checks=False)
    assert result.converged
    return result


@pytest.mark.parametrize('parameter, delta, tol', [('reduced_volume', 2.5e-4, 5e-5),
                                                   ('c0', 1e-3, 1e-6)])
def test_the_tangent_is_the_derivative_of_the_solution(solved, parameter, delta, tol):
    """phi and nu at p +- delta (Newton from the solution) against the tangent: measured
    errors 1.2e-5 (v: the difference's own delta^2 error, 1.9e-4 at delta 1e-3) and 1.7e-8
    (c0: F is quadratic in c0)."""
    t = pf.tangent(solved, parameter)
    ends = []
    for d in (delta, -delta):
        scene = pf.Scene(**{**dict(reduced_volume=0.9, branch='oblate'),
                            parameter: getattr(solved.scene, parameter) + d})
        r = pf.solve(scene, solved.grid, EPS, start=solved, options=dict(pf_stage1='none'),
                     checks=False)
        assert r.converged
        ends.append(r)
    dphi = (ends[0].phi - ends[1].phi) / (2 * delta)
    dnu = (ends[0].nu - ends[1].nu) / (2 * delta)
    assert np.abs(t.phi - dphi).max() < tol * np.abs(dphi).max()
    np.testing.assert_allclose(t.nu, dnu, rtol=10 * tol, atol=tol * np.abs(dnu).max())


def test_along_moves_the_state_and_the_parameter(solved):
    t = pf.tangent(solved, 'c0')
    moved = pf.along(solved, t, 0.1)
    assert moved.attrs['c0'] == pytest.approx(0.1)
    np.testing.assert_allclose(moved.phi, solved.phi + 0.1 * t.phi)
    np.testing.assert_allclose(moved.nu, solved.nu + 0.1 * t.nu)
    with pytest.raises(ValueError, match='no continuation'):
        pf.tangent(solved, 'eps')
