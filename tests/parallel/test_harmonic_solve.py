"""Solves with azimuthal harmonics through the public API (one rank under pytest, two under
`mpiexec -n 2`): an axisymmetric state is an equilibrium of the harmonic solver with the
axisymmetric energy, a fresh start leaves it along its unstable mode for a lower
equilibrium whose index (within the harmonics) is 0 where the axisymmetric state's is 1,
and the 3D level set is measured."""
import dataclasses

import numpy as np
import pytest

import pfmembrane as pf
from pfmembrane.io.options import UsageError

pytestmark = pytest.mark.slow
SCENE = pf.Scene(reduced_volume=0.8, branch='oblate')
EPS = 0.055  # on 3,000 nodes


@pytest.fixture(scope='module')
def axisymmetric():
    grid = pf.Grid.uniform(SCENE, nodes=3000)
    result = pf.solve(SCENE, grid, eps=EPS, checks=True)
    assert result.converged
    return grid, result


def test_an_axisymmetric_state_stays_with_its_energy(axisymmetric):
    grid, axi = axisymmetric
    phi = np.column_stack([axi.phi, np.zeros_like(axi.phi)])
    r = pf.solve(dataclasses.replace(SCENE, harmonics=1, dihedral=2), grid, EPS,
                 start=dataclasses.replace(axi, phi=phi), options={'pf_stage1': 'none'})
    assert r.converged and r.phi.shape == (grid.n_nodes, 2)
    # the m = 2 gradient vanishes by symmetry: chi_2 stays zero to rounding
    assert np.abs(r.phi[:, 1]).max() < 1e-12
    assert r.energy == pytest.approx(axi.energy, rel=1e-12)
    assert list(r.attrs['harmonics']) == [0, 2]


@pytest.fixture(scope='module')
def pushed(axisymmetric):
    """A fresh solve with m = 0, 2, 4: the axisymmetric scene solved, then pushed
    along m = 2 alone; its energy path recorded."""
    grid, _ = axisymmetric
    return pf.solve(dataclasses.replace(SCENE, harmonics=2, dihedral=2), grid, EPS, checks=True,
                    options={'pf_path': True})


def test_the_unstable_m2_mode_leads_below_the_axisymmetric_family(axisymmetric, pushed):
    grid, axi = axisymmetric
    # the discocyte's m = 2 instability, as on the paper's grid at eps 0.04; m = 4 stable
    lowest = [s.eigenvalues[0] for s in pf.stability(axi, modes=4, nev=2)]
    assert lowest[2] < 0 < lowest[4]
    r = pushed
    assert r.converged
    assert list(r.attrs['start_unstable_m']) == [2]
    assert r.energy < axi.energy
    # the index within m = 0, 2, 4 (the exact coupled Hessian's inertia): 1 at the
    # axisymmetric state (its m = 2 mode), 0 at the state it leads to
    lifted = np.zeros((grid.n_nodes, 3))
    lifted[:, 0] = axi.phi
    at_axi = dataclasses.replace(axi, phi=lifted, attrs={**axi.attrs, 'harmonics_highest': 2,
                                                         'dihedral': 2, 'harmonics': [0, 2, 4]})
    assert pf.stability(at_axi) == 1 and at_axi.attrs['index_harmonics'] == 1
    assert pf.stability(r) == 0
    # what flags a solve that came back to the saddle, and not one that left it
    from pfmembrane.equilibrium import returned
    assert returned(at_axi, [2]) == [2] and returned(r, [2]) == []
    assert np.abs(r.phi[:, 1]).max() > 1e-2
    # the 3D level set: one sphere; its energy put on the constraints (a level of the
    # scene's reduced volume, scaled) against the axisymmetric curve's (the smallest
    # correction onto them): two O(d^2) projections and the marching error, measured
    # 1.0e-3 apart on the axisymmetric state
    assert (r.attrs['topology'], r.attrs['genus']) == ('1 sphere', 0.0)
    assert r.attrs['level_set_energy'] == pytest.approx(axi.attrs['level_set_energy'], rel=2e-3)


def test_the_energy_falls_on_the_constraints_to_the_new_equilibrium(axisymmetric, pushed):
    # -pf_path: E of every iterate put back on A and V (to 1e-12 of their scales, so E
    # to about 1e-12 of itself). The push starts below the axisymmetric energy, E falls
    # at every iterate of both stages (measured: by 5.6e-3 in all; once converged it
    # moves by 1e-13) to the equilibrium's; E unprojected rises where stage 1 leaves
    # the constraints
    from pfmembrane.parallel.problem import path_line
    grid, axi = axisymmetric
    path, raw = pushed.attrs['energy_path'], pushed.attrs['energy_history']
    assert len(path) == len(raw) and len(path) >= 4
    assert path[0] < axi.energy
    assert np.all(np.diff(path) <= 1e-12 * path[0])
    assert 'falls at every one of' in path_line(path)
    assert 'rises at 1 of 3 iterations (first at 2' in path_line([3.0, 2.0, 2.5, 1.0])
    assert path[-1] == pytest.approx(pushed.energy, rel=1e-12)
    assert np.any(np.diff(raw) > 0)


def test_an_iterate_is_put_on_the_constraints(pushed):
    # Solver.project: a field far off them (A and V off by percents) meets them to 1e-12
    # of their scales, the solver's own gradients untouched; an equilibrium keeps its E
    from pfmembrane.parallel.problem import Problem, next_prefix
    with Problem(pushed.grid, pushed.scene, EPS, next_prefix()) as problem:
        P, solver = problem.assembly, problem.solver
        x = problem.vec(0.9 * pushed.phi)
        vals, res = solver.evaluate(x)
        gA = solver.gA.copy()
        assert np.abs(res / solver.scale).max() > 1e-2
        E = solver.project(x)
        y = solver._projection[2]
        assert np.all(np.abs(P.constraints(P.values(y)) - P.targets) <= 1e-12 * solver.scale)
        assert E == pytest.approx(P.values(y)[0], rel=1e-14)
        assert solver.gA.equal(gA)
        assert solver.project(problem.vec(pushed.phi)) == pytest.approx(pushed.energy,
                                                                        rel=1e-12)


def test_the_curved_push_follows_the_centre_manifold_to_second_order(axisymmetric):
    # Along x0 + t d + t^2 w, nu + t^2 dnu out of the discocyte along its critical m = 2
    # mode d, the residual's even part F(t) + F(-t) - 2 F(0) loses its t^2 term (w
    # slaves m = 0 and 4 to the mode); along the straight push x0 + t d it keeps it.
    # Measured 2.4e-4 and 3.8e-4 of the straight push's at t = 0.5, 1 (units of the push).
    from pfmembrane.equilibrium import critical_start
    from pfmembrane.parallel.problem import Problem, next_prefix
    grid, axi = axisymmetric
    scene = dataclasses.replace(SCENE, harmonics=2, dihedral=2)
    lift, pushed_m = critical_start(axi, scene, grid, {'pf_push': 'straight'})
    assert list(pushed_m) == [2] and lift.attrs['start_push'] == 0.02
    with Problem(grid, scene, EPS, next_prefix()) as problem:
        base = np.zeros_like(lift.phi)
        base[:, 0] = lift.phi[:, 0]
        x0, d = problem.vec(base), problem.vec(lift.phi - base)
        problem.assembly.hold(x0)
        problem.nu = lift.nu
        w, dnu = problem.slaved(x0, d)
        F0 = problem.residual(x0, problem.bordered_vec())

        def even(t, curved):
            F = []
            for s in (t, -t):
                x = x0.copy()
                x.axpy(s, d)
                x.axpy(s * s * curved, w)
                problem.nu = lift.nu + s * s * curved * dnu
                F.append(problem.residual(x, problem.bordered_vec()))
            F[0].axpy(1.0, F[1])
            F[0].axpy(-2.0, F0)
            return F[0].norm()

        for t in (0.5, 1.0):
            assert even(t, 1.0) < 1e-3 * even(t, 0.0)


def test_a_curved_push_starts_on_the_branch():
    # The oblate at C0 3.5, R 0.4, v 0.9 on the test grid: unstable to m = 3, whose branch
    # leaves it supercritically. The curved push lands at the same equilibrium as the
    # straight one in fewer stage-1 steps (measured 17 against 29), from an amplitude
    # between the straight push's and PUSH_MAX (0.37).
    from pfmembrane.equilibrium import PUSH_MAX
    scene = pf.Scene(reduced_volume=0.9, c0=3.5, radius=0.4, branch='oblate', symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=3000)
    scene = dataclasses.replace(scene, harmonics=2, dihedral=3)
    curved, straight = (pf.solve(scene, grid, EPS, options={'pf_push': push})
                        for push in ('curved', 'straight'))
    assert curved.converged and straight.converged
    assert list(curved.attrs['start_unstable_m']) == [3]
    assert curved.energy == pytest.approx(straight.energy, rel=1e-10)
    assert 0.02 < curved.attrs['start_push'] < PUSH_MAX
    assert straight.attrs['start_push'] == 0.02
    assert curved.attrs['stage1_iterations'] < straight.attrs['stage1_iterations']
    assert np.abs(curved.phi[:, 1]).max() > 1.0


def test_a_kept_preconditioner_reaches_the_same_equilibrium(axisymmetric, pushed):
    """-pf_refresh 0 assembles and factors the block preconditioner at every Newton
    step; the default keeps it while GMRES converges as fast: the same steps, the same
    equilibrium, fewer factorizations."""
    grid, _ = axisymmetric
    fresh = pf.solve(dataclasses.replace(SCENE, harmonics=2, dihedral=2), grid, EPS,
                     options={'pf_refresh': 0})
    assert fresh.converged
    assert fresh.energy == pytest.approx(pushed.energy, rel=1e-10)
    # the same shape, or the same turned by 90 degrees (the critical mode's sign)
    assert min(np.abs(fresh.phi * [1, s, 1] - pushed.phi).max() for s in (1, -1)) < 1e-6
    assert fresh.attrs['factorizations'] > pushed.attrs['factorizations']


def test_a_non_axisymmetric_branch_is_followed_in_v(pushed):
    # pseudo-arclength continuation of the m = 2 state (with the exact coupled Hessian,
    # which a branch with harmonics takes): along a branch dE/dv = nu_V dV0/dv (A0
    # fixed), so between two points E moves by the trapezoid of nu_V over V0's change,
    # to O(dv^3)
    with pytest.raises(ValueError, match='coupled'):
        next(pf.continuation(pushed, 'reduced_volume', -0.002, 1,
                             options={'pf_hessian': 'block'}))
    points = list(pf.continuation(pushed, 'reduced_volume', -0.002, 2))
    assert len(points) == 2
    chain = [pushed] + points
    for a, b in zip(chain, chain[1:]):
        assert b.phi.shape == a.phi.shape and b.attrs['index_0'] == 0
        v = [x.attrs['reduced_volume'] for x in (a, b)]
        dV0 = np.diff([x.scene.volume for x in (a, b)])[0]
        trapezoid = 0.5 * (a.nu[1] + b.nu[1]) * dV0
        assert v[1] < v[0]
        assert b.energy - a.energy == pytest.approx(trapezoid, rel=1e-4)
    # the m = 2 part stays: the branch is the non-axisymmetric one
    assert all(np.abs(p.phi[:, 1]).max() > 1e-2 for p in points)


def test_a_non_axisymmetric_branch_is_followed_in_c0(pushed):
    # the m = 2 state followed in C0: each point is the equilibrium that Newton (stage 2
    # alone) reaches at its C0 from the point before, and the m = 2 part stays
    chain = [pushed] + list(pf.continuation(pushed, 'c0', 0.05, 2))
    assert len(chain) == 3
    for a, b in zip(chain, chain[1:]):
        assert b.scene.c0 > a.scene.c0 and b.attrs['index_0'] == 0
        newton = pf.solve(b.scene, pushed.grid, EPS, start=a, options={'pf_stage1': 'none'})
        assert newton.converged
        assert newton.energy == pytest.approx(b.energy, rel=1e-9)
        assert np.abs(newton.phi - b.phi).max() < 1e-5
        assert np.abs(b.phi[:, 1]).max() > 1e-2


def test_with_sines_a_turned_state_is_the_same_equilibrium(pushed):
    # Without a mirror plane through the axis (sines), the m = 2 state turned by alpha
    # is an equilibrium of the same energy; the phase condition holds the turn where
    # the start puts it (the rotation is otherwise a zero mode: no factorization, no
    # index), so the solve stays turned and its index within the harmonics is 0.
    alpha = 0.3
    c = pushed.phi
    turned = np.column_stack([c[:, 0]] + [np.cos(m * alpha) * c[:, j] for j, m in ((1, 2), (2, 4))]
                             + [np.sin(m * alpha) * c[:, j] for j, m in ((1, 2), (2, 4))])
    scene = dataclasses.replace(SCENE, harmonics=2, dihedral=2, mirror=False)
    start = dataclasses.replace(pushed, phi=turned,
                                attrs={**pushed.attrs, 'harmonics': [0, 2, 4, 2, 4]})
    r = pf.solve(scene, pushed.grid, EPS, start=start, options={'pf_stage1': 'none'})
    assert r.converged and r.phi.shape == turned.shape
    assert r.energy == pytest.approx(pushed.energy, rel=1e-9)
    assert abs(r.nu[-1]) < 1e-6 * abs(r.nu[0])  # nu_phase: the turn costs nothing
    assert np.abs(r.phi - turned).max() < 1e-6 * np.abs(turned).max()
    assert pf.stability(r) == 0


def test_a_start_with_fewer_harmonics_starts_the_others_at_zero(pushed):
    # m = 0, 2, 4 solved, then m = 0, 2, 4, 6 from it: the first iterate is the same field
    # (chi_6 = 0, so the same energy), and the larger space's equilibrium lies below it
    scene = dataclasses.replace(SCENE, harmonics=3, dihedral=2)
    r = pf.solve(scene, pushed.grid, EPS, start=pushed, options={'pf_stage1': 'none'})
    assert r.converged and list(r.attrs['harmonics']) == [0, 2, 4, 6]
    assert r.attrs['energy_history'][0] == pytest.approx(pushed.energy, rel=1e-12)
    assert r.energy < pushed.energy
    assert np.abs(r.phi[:, 3]).max() > 0.0
    # a start whose harmonics the scene lacks (m = 2, 4 against m = 0, 3, 6)
    with pytest.raises(UsageError, match="c2, c4"):
        pf.solve(dataclasses.replace(SCENE, harmonics=2, dihedral=3), pushed.grid, EPS,
                 start=pushed)
