"""The tangent of a branch (pf.tangent, Solver.tangent) against central differences of
converged solves, in the reduced volume and in the spontaneous curvature."""
import sys

import numpy as np
import pytest

import pfmembrane as pf
from pfmembrane.branching import asymmetric

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


def test_arclength_points_solve_the_scene_at_their_parameter(solved):
    """Each point of pf.continuation is an equilibrium of the scene at its own v: a
    bordered Newton solve from it there stops at once with the same energy (measured: 0
    or 1 iteration, 1e-13); the step grows, the index from the factorization's inertia is
    that of the m = 0 mode Hessian, and no fold is reported on this regular stretch."""
    from pfmembrane.parallel.problem import Problem
    points = list(pf.continuation(solved, 'reduced_volume', ds=0.02, steps=3, checks=False))
    assert len(points) == 3
    vs = [p.attrs['reduced_volume'] for p in points]
    assert 0.9 < vs[0] < vs[1] < vs[2] < 0.96
    assert vs[2] - vs[1] > vs[0] - 0.9                    # the step grew
    for p in points:
        scene = pf.Scene(reduced_volume=p.attrs['reduced_volume'], branch='oblate')
        again = pf.solve(scene, solved.grid, EPS, start=p, options=dict(pf_stage1='none'),
                         checks=False)
        assert again.attrs['stage2_iterations'] <= 1
        assert again.energy == pytest.approx(p.energy, rel=1e-11)
        assert p.attrs['fold'] == 0 and p.attrs['index_change'] == 0
    last = points[-1]
    problem = Problem(solved.grid, last.scene, EPS, 'modes_test_')
    analysis = problem.modes(last.phi, last.nu[0])
    try:
        assert analysis.spectrum(0).index == last.attrs['index_0'] == 0
    finally:
        problem.close()


def test_the_corrector_lands_on_its_hyperplane_from_either_predictor(solved):
    """Two steps in v by Solver.arclength: the second from the tangent predictor and from
    the one with the second-order term of the last two points (branching._bend). That term
    brings the start closer to the branch (measured |F| 0.026 against 0.123), both reach
    the same point of the same hyperplane (measured 1.1e-12 apart in v), and from the
    closer start the last step is a chord step on the factorization before (measured:
    3 steps on 3 factorizations from the tangent alone, on 2 with the term)."""
    from pfmembrane.branching import Branch, _bend, _unit, arclength, branch_tangent
    with Branch(solved, 'reduced_volume') as branch:
        problem, x, ds = branch.problem, branch.x, 0.02
        (bx, bnu), _ = branch_tangent(problem, x, 'reduced_volume', 0.9)
        t = _unit(bx, bnu, 1.0)
        x0, nu0 = x.copy(), problem.nu.copy()
        p1, _, _, _, (bx, bnu) = arclength(problem, x, 'reduced_volume', 0.9, t, ds, 7)
        t1 = _unit(bx, bnu, 1.0)
        x1, nu1 = x.copy(), problem.nu.copy()
        F = problem.bordered_vec()
        starts, ends = [], []
        for bend in (None, _bend((x0, nu0, 0.9, ds), x1, nu1, p1, t1, ds)):
            bend_x, bend_nu, bend_p = bend or (x.duplicate(), 0.0, 0.0)
            x1.copy(x)
            x.axpy(ds, t1[0])
            x.axpy(1.0, bend_x)
            problem.nu = nu1 + ds * t1[1] + bend_nu
            problem.at('reduced_volume', p1 + ds * t1[2] + bend_p)
            starts.append(problem.residual(x, F).norm())
            x1.copy(x)
            problem.nu = nu1.copy()
            problem.at('reduced_volume', p1)
            before = problem.solver.factorizations
            p2, its, factored, _, _ = arclength(problem, x, 'reduced_volume', p1, t1, ds, 7,
                                                bend)
            assert problem.solver.factorizations - before == factored
            ends.append((p2, x.copy(), its, factored))
        assert starts[1] < 0.8 * starts[0]
        assert ends[1][0] == pytest.approx(ends[0][0], abs=1e-9)
        d = ends[1][1].copy()
        d.axpy(-1.0, ends[0][1])
        assert d.norm(3) < 1e-7 * ends[0][1].norm(3)
        assert ends[0][3] <= ends[0][2] and ends[1][3] < ends[1][2]


def test_continuation_in_c0_goes_both_ways(solved):
    down = next(pf.continuation(solved, 'c0', ds=-0.05, steps=1, checks=False))
    up = next(pf.continuation(solved, 'c0', ds=0.05, steps=1, checks=False))
    assert down.attrs['c0'] < 0 < up.attrs['c0']
    assert up.attrs['dp_ds'] > 0 > down.attrs['dp_ds']


def _up_down_asymmetry(result):
    from pfmembrane.analysis import levelset
    from pfmembrane.io.checkpoint import Checkpoint
    ck = Checkpoint(nodes=result.nodes, phi=result.phi, attrs=dict(result.attrs)).unfolded()
    return levelset.up_down_asymmetry(levelset.level_set(ck), result.scene.radius)


def test_the_prolate_bifurcates_to_pears_and_a_switch_follows_them():
    """The full-box prolate at v = 0.8 (eps 0.04) in c0 = 2 C0 R from 2.5: its index goes
    0 -> 1 without a fold near c0 2.72 (runs/atlas/notes.md), with an eigenvalue near zero
    there; the switched continuation leaves the up-down symmetric shapes, its asymmetry
    growing as c0 falls (the subcritical pears, index 1)."""
    comm = pf.api.petsc(sys.argv[:1]).COMM_SELF
    R = 0.4
    scene = pf.Scene(reduced_volume=0.8, c0=2.5 / (2 * R), radius=R, box=(0.55, 2.75),
                     branch='prolate')
    grid = pf.Grid.uniform(scene, nodes=3079, comm=comm)
    res = pf.solve(scene, grid, eps=0.04, options={'pf_start': 'sharp'}, checks=False)
    route = []
    for res in pf.continuation(res, 'c0', 0.05, 8, ds_max=0.05, checks=False):
        route.append(res)
        if res.attrs['index_change']:
            break
    assert [r.attrs['index_0'] for r in route[:-1]] == [0] * (len(route) - 1)
    assert route[-1].attrs['index_0'] == 1 and route[-1].attrs['fold'] == 0
    assert 2.70 < 2 * R * route[-1].attrs['c0'] < 2.78
    assert abs(_up_down_asymmetry(route[-1])) < 1e-3
    pears = list(pf.continuation(route[-1], 'c0', 0.1, 6, switch=True, checks=False))[:3]
    assert abs(route[-1].attrs['critical_eigenvalue']) < 1e-3
    asymmetry = [abs(_up_down_asymmetry(p)) for p in pears]
    assert 0.02 < asymmetry[0] < asymmetry[1] < asymmetry[2]
    assert not asymmetric(route[-1]) and all(asymmetric(p) for p in pears)
    c0 = [p.attrs['c0'] for p in pears]
    assert c0[0] > c0[1] > c0[2]
    assert all(p.attrs['index_0'] == 1 for p in pears)
