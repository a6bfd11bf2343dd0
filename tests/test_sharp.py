"""Sharp-interface Canham-Helfrich reference shapes (pfmembrane.sharp)."""
import numpy as np
import pytest

from pfmembrane.sharp import solver as sharp
from pfmembrane.sharp import energy_reference, solve

R0 = 0.4
LITERATURE = {'oblate': 9.12657, 'prolate': 8.71756}   # v = 0.8, k = 1, C0 = 0


def polyline_area_volume_centroid(r, z):
    """Area, volume and volume centroid of the surface of revolution of a polyline."""
    rm, zm, dz = 0.5 * (r[1:] + r[:-1]), 0.5 * (z[1:] + z[:-1]), np.diff(z)
    volume = np.sum(np.pi * rm ** 2 * dz)
    return (np.sum(2 * np.pi * rm * np.hypot(np.diff(r), dz)), volume,
            np.sum(np.pi * rm ** 2 * dz * zm) / volume)


def test_sphere_energy_is_2pi():
    shape = solve(1.0, radius=R0)
    assert abs(shape.energy - 2 * np.pi) < 1e-8 * 2 * np.pi
    assert np.allclose(np.hypot(shape.r, shape.z), R0, atol=1e-12)


def test_sphere_with_spontaneous_curvature():
    c0, k = 0.5 / R0, 2.0
    shape = solve(1.0, 'prolate', c0=c0, radius=R0, k=k)
    assert shape.energy == pytest.approx(2 * np.pi * k * (1 - c0 * R0) ** 2, rel=1e-12)


@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_literature_energy_at_v08(branch):
    shape = solve(0.8, branch, radius=R0)
    assert abs(shape.energy / LITERATURE[branch] - 1) < 1e-5


@pytest.mark.parametrize('branch, v', [('oblate', 0.8), ('prolate', 0.8),
                                       pytest.param('stomatocyte', 0.6, marks=pytest.mark.slow)])
def test_constraints_hold(branch, v):
    shape = solve(v, branch, radius=R0)
    assert abs(shape.area / (4 * np.pi * R0 ** 2) - 1) < 1e-10
    assert abs(shape.volume / (v * 4 * np.pi * R0 ** 3 / 3) - 1) < 1e-10


@pytest.mark.filterwarnings('ignore:.*not resolved')
@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_energy_error_decreases_with_resolution(branch):
    converged = solve(0.8, branch, radius=R0, n=64).energy
    errors = [abs(solve(0.8, branch, radius=R0, n=n).energy - converged) for n in (4, 6, 8, 12)]
    assert all(finer < coarser for coarser, finer in zip(errors, errors[1:]))
    assert errors[-1] < 1e-8 * converged


@pytest.mark.filterwarnings('ignore:.*not resolved')
@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_general_path_matches_symmetric_path(branch):
    general = solve(0.8, branch, radius=R0, n=16, symmetric=False)
    assert general.energy == pytest.approx(solve(0.8, branch, radius=R0).energy, rel=1e-11)
    assert abs(general.area / (4 * np.pi * R0 ** 2) - 1) < 1e-10


@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_curve_matches_area_volume_and_is_centred(branch):
    shape = solve(0.8, branch, radius=R0)
    area, volume, centroid = polyline_area_volume_centroid(shape.r, shape.z)
    assert shape.r[0] == shape.r[-1] == 0 and np.all(shape.r[1:-1] > 0)
    assert area == pytest.approx(shape.area, rel=1e-4)
    assert volume == pytest.approx(shape.volume, rel=1e-4)
    assert abs(centroid) < 1e-10 * R0
    height, width = np.ptp(shape.z), 2 * shape.r.max()
    assert (height < width) if branch == 'oblate' else (height > width)


@pytest.mark.parametrize('branch', ['oblate', 'prolate'])
def test_multipliers_are_energy_derivatives(branch):
    # C0 = 0 is scale invariant: dE = tension dA0 + pressure dV0 = 0 under scaling.
    shape = solve(0.8, branch, radius=R0)
    assert abs(2 * shape.area * shape.tension + 3 * shape.volume * shape.pressure) < 1e-9 * shape.energy
    # dE/dv = pressure dV0/dv and dE/dR0 = tension dA0/dR0 + pressure dV0/dR0.
    c0, k, h = 0.7, 1.3, 1e-4
    shape = solve(0.8, branch, c0=c0, radius=R0, k=k)
    dE_dv = (solve(0.8 + h, branch, c0=c0, radius=R0, k=k).energy
             - solve(0.8 - h, branch, c0=c0, radius=R0, k=k).energy) / (2 * h)
    dE_dR = (solve(0.8, branch, c0=c0, radius=R0 + h, k=k).energy
             - solve(0.8, branch, c0=c0, radius=R0 - h, k=k).energy) / (2 * h)
    assert dE_dv == pytest.approx(shape.pressure * 4 * np.pi * R0 ** 3 / 3, rel=1e-6)
    assert dE_dR == pytest.approx(shape.tension * 8 * np.pi * R0
                                  + shape.pressure * 4 * np.pi * 0.8 * R0 ** 2, rel=1e-6)


@pytest.mark.parametrize('c', [0.0, 0.5, -1.0])
def test_sphere_multipliers_are_limits_of_the_branches(c):
    sphere = solve(1.0, c0=c)
    for branch in ('oblate', 'prolate'):
        near = solve(0.9999, branch, c0=c)
        assert near.tension == pytest.approx(sphere.tension, rel=1e-2)
        assert near.pressure == pytest.approx(sphere.pressure, rel=1e-2)


def test_spontaneous_curvature_scales_with_radius_and_k():
    unit = solve(0.8, 'prolate', c0=0.5)
    scaled = solve(0.8, 'prolate', c0=0.5 / R0, radius=R0, k=3.0)
    assert scaled.energy == pytest.approx(3.0 * unit.energy, rel=1e-12)
    assert scaled.tension == pytest.approx(3.0 * unit.tension / R0 ** 2, rel=1e-10)
    assert np.allclose(scaled.z, R0 * unit.z, atol=1e-12)
    # Positive C0 favours the curvature of the sphere, so the energy drops.
    assert unit.energy < solve(0.8, 'prolate').energy


@pytest.mark.slow
def test_stomatocyte_v055():
    shape = solve(0.55, 'stomatocyte', radius=R0)
    # n-converged value (n = 192 and the default agree to 1e-12, validation.md).
    assert shape.energy == pytest.approx(12.4647979843, rel=1e-9)
    # Below the oblate-stomatocyte transition (v ~ 0.59) the stomatocyte wins.
    assert shape.energy < solve(0.55, 'oblate', radius=R0).energy
    area, volume, centroid = polyline_area_volume_centroid(shape.r, shape.z)
    assert volume == pytest.approx(shape.volume, rel=1e-4)
    assert abs(centroid) < 1e-4 * R0
    # Up-down asymmetric: the end pole lies inside, far above the bottom pole.
    assert shape.z[0] == shape.z.min() and shape.z[-1] < shape.z.max() - 0.5 * R0


@pytest.mark.slow
@pytest.mark.filterwarnings('ignore:.*not resolved')
def test_stomatocyte_branch_ends():
    with pytest.raises(RuntimeError, match='stomatocyte'):
        solve(0.7, 'stomatocyte', n=32)


def test_unresolved_spectrum_warns():
    with pytest.warns(RuntimeWarning, match='not resolved'):
        solve(0.6, 'stomatocyte', n=16)


@pytest.mark.parametrize('kwargs', [
    dict(reduced_volume=0.8, branch='discocyte'),
    dict(reduced_volume=0.0, branch='oblate'),
    dict(reduced_volume=-0.3, branch='prolate'),
    dict(reduced_volume=1.2, branch='oblate'),
    dict(reduced_volume=float('nan'), branch='oblate'),
    dict(reduced_volume=0.6, branch='stomatocyte', symmetric=True),
    dict(reduced_volume=0.8, branch='oblate', n=1),
])
def test_bad_input_raises(kwargs):
    with pytest.raises(ValueError):
        solve(**kwargs)


def test_energy_reference_is_cached_solve():
    energy_reference.cache_clear()
    first = energy_reference(0.8, 'oblate', radius=R0)
    assert first == solve(0.8, 'oblate', radius=R0).energy
    assert energy_reference(0.8, 'oblate', radius=R0) == first
    assert energy_reference.cache_info().hits == 1


def test_gradients_match_finite_differences():
    grid = sharp._Grid(8, symmetric=False)
    x = np.concatenate([0.05 * np.cos(np.arange(8)), [1.1]])
    values, gradients = grid.functionals(x[None], 0.3)
    h = 1e-6
    for i in range(x.size):
        step = h * np.eye(x.size)[i]
        difference = (grid.functionals((x + step)[None], 0.3)[0]
                      - grid.functionals((x - step)[None], 0.3)[0])[0] / (2 * h)
        assert np.allclose(gradients[0][:, i], difference, rtol=1e-7, atol=1e-8)


def tangent_angle(shape):
    """theta, psi and length of a solved curve, from its chords."""
    dr, dz = np.diff(shape.r), np.diff(shape.z)
    chords = np.hypot(dr, dz)
    s = np.concatenate([[0.0], np.cumsum(chords)])
    mid = 0.5 * (s[1:] + s[:-1])
    return np.pi * mid / s[-1], np.unwrap(np.arctan2(dz, dr)), s[-1]


@pytest.mark.parametrize('branch, c0', [('oblate', 0.0), ('prolate', 1.0)])
def test_shape_energy_is_second_order_in_the_distance_to_the_minimum(branch, c0):
    shape = solve(0.8, branch, c0=c0, radius=0.4, k=2.0)
    theta, psi, length = tangent_angle(shape)
    args = (length, shape.area, shape.volume, c0, 2.0)

    assert sharp.shape_energy(theta, psi, *args)[0] == pytest.approx(shape.energy, rel=1e-8)
    excess, excess_curve = [], []
    for delta in (2e-2, 1e-2):
        # an odd mode: the closure constraint acts too on the prolate path
        energy, energy_curve = sharp.shape_energy(theta, psi + delta * np.sin(3 * theta), *args)
        excess.append(energy - shape.energy)
        excess_curve.append(abs(energy_curve - shape.energy))
    assert min(excess) > 0.0                                 # the solved shape is a minimum
    assert excess[0] / excess[1] == pytest.approx(4.0, rel=0.1)
    assert excess_curve[0] / excess_curve[1] == pytest.approx(2.0, rel=0.1)


@pytest.mark.parametrize('c0', [3.7, 4.0])
def test_the_pear_mode_is_antisymmetric_and_its_eigenvalue_is_the_energy_change(c0):
    """At v = 0.8, below and above the pear bifurcation (reduced c0 3.85): the mode lies in
    the odd sine modes (up-down antisymmetric), and moving the prolate along it, back onto
    the constraints, changes E by (1/2) lambda delta^2, measured without the Hessian."""
    R = 0.4
    value, mode = sharp.pear_mode(0.8, c0 / (2 * R), R)
    grid, x = sharp._embedded_prolate(0.8, c0 / 2, 32)
    odd = np.append(grid.modes % 2 == 1, False)
    assert np.linalg.norm(mode[~odd]) < 1e-8
    targets = np.array([4 * np.pi, 0.8 * 4 * np.pi / 3, 0.0])
    base = sharp._evaluate(grid, x, c0 / 2)[0][0]
    delta = 1e-3
    moved = sharp._project(grid, x + delta * mode, targets, c0 / 2)
    change = sharp._evaluate(grid, moved, c0 / 2)[0][0] - base
    assert change == pytest.approx(0.5 * value * delta ** 2, rel=2e-2)
    assert np.sign(value) == (1 if c0 < 3.85 else -1)


def test_the_pear_bifurcation_is_resolved_in_the_modes():
    """D_pe at v = 0.8 from 32 and 48 modes agree to 1e-8 (reduced c0 3.85478)."""
    R = 0.4
    c32, c48 = (2 * R * sharp.pear_bifurcation(0.8, (4.6, 5.0), R, n) for n in (32, 48))
    assert c32 == pytest.approx(c48, abs=1e-8)
    assert 3.85 < c32 < 3.86
