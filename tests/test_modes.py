"""Azimuthal stability modes (pfmembrane.kernels.azimuthal, pfmembrane.parallel.stability) of an
in-process solve on one rank: H_m against finite differences of the 3D Lagrangian, the
eigensolver against dense linear algebra, the rigid motions in m = 1, the moment
constraint in m = 0."""
import sys

import numpy as np
import pytest
import scipy.linalg
import scipy.sparse

import pfmembrane as pf
from pfmembrane.kernels.functionals import F_A, F_E, SQRT2

pytestmark = pytest.mark.slow

SCENE = pf.Scene(reduced_volume=0.8, branch='oblate')
EPS = 0.06


@pytest.fixture(scope='module')
def comm():
    return pf.api.petsc(sys.argv[:1]).COMM_SELF


def _solved(comm, nodes):
    grid = pf.Grid.uniform(SCENE, nodes=nodes, comm=comm)
    result = pf.solve(SCENE, grid, eps=EPS, checks=False)
    assert result.converged
    return result


@pytest.fixture(scope='module')
def solved(comm):
    return _solved(comm, 1500)


@pytest.fixture(scope='module')
def analysis(solved):
    from pfmembrane.parallel.problem import Problem
    with Problem(solved.grid, SCENE, EPS, 'modes_test_') as problem:
        yield problem.modes(solved.phi, solved.nu[0])


def _lagrangian_3d(a, phi, chi, m, t, nu, n_theta=32):
    """E - nu_A A of phi + t psi cos(m theta), psi = r^m chi_h, from the 3D fields on
    the quadrature points times a trapezoid rule in theta (exact: the integrand is a
    trigonometric polynomial of degree 6 m < n_theta)."""
    o = a.forms.ops
    u, ur, uz, lap = (o.B0 @ phi + o.b0, o.Br @ phi + o.br, o.Bz @ phi + o.bz,
                      o.BL @ phi + o.bL)
    c, cr, cz, cl = o.B0 @ chi, o.Br @ chi, o.Bz @ chi, o.BL @ chi
    r = o.r
    psi = r ** m * c
    psi_r = r ** m * cr + m * r ** (m - 1.0) * c
    psi_z = r ** m * cz
    # psi_rr + psi_r / r + psi_zz of r^m chi by the product rule
    lap_psi = r ** m * cl + 2 * m * r ** (m - 1.0) * cr + m * m * r ** (m - 2.0) * c
    theta = 2 * np.pi * np.arange(n_theta) / n_theta
    cos, sin = np.cos(m * theta), np.sin(m * theta)
    U = u[:, None] + t * psi[:, None] * cos
    grad2 = ((ur[:, None] + t * psi_r[:, None] * cos) ** 2
             + (uz[:, None] + t * psi_z[:, None] * cos) ** 2
             + (t * m * psi[:, None] * sin / r[:, None]) ** 2)          # (u_theta / r)^2
    lap3 = lap[:, None] + t * (lap_psi - m * m * psi / r ** 2)[:, None] * cos
    W = EPS * lap3 + (U / EPS + SQRT2 * SCENE.c0) * (1 - U * U)
    E = F_E * SCENE.k / (2 * EPS) * np.dot(o.w, (W * W).mean(axis=1))
    A = F_A * np.dot(o.w, (0.5 * EPS * grad2 + (U * U - 1) ** 2 / (4 * EPS)).mean(axis=1))
    return E - nu * A


@pytest.mark.parametrize('m', [0, 1, 2, 3])
def test_mode_hessian_is_the_second_variation_of_the_3d_lagrangian(solved, analysis, m):
    a = analysis
    lay = a.layout
    x = a.problem.create_vec()
    x.setArray(solved.phi[lay.order])
    phi = a.problem.local(x)
    chi = np.random.default_rng(m).standard_normal(lay.nglobal)
    K = a.assemble(m)
    X, Y = K.createVecs()
    X.zeroEntries()
    X.getArray()[:lay.nowned] = chi
    K.mult(X, Y)
    exact = X.dot(Y)
    t = 1e-3 / np.abs(a.forms.field(chi, m)).max()
    second = [(_lagrangian_3d(a, phi, chi, m, s, solved.nu[0])
               - 2 * _lagrangian_3d(a, phi, chi, m, 0.0, solved.nu[0])
               + _lagrangian_3d(a, phi, chi, m, -s, solved.nu[0])) / s ** 2
              for s in (t, t / 2)]
    fd = (4 * second[1] - second[0]) / 3   # Richardson: the t^2 term of the sextic goes
    assert exact == pytest.approx(fd, rel=1e-9)   # measured 2e-13 ... 2e-12


def test_m0_is_the_hessian_of_the_solver(solved, analysis):
    from pfmembrane.kernels.functionals import Functionals
    a = analysis
    d = solved.grid.discrete
    phi = solved.phi[d.layout.order]
    H = Functionals(d.ops, EPS, SCENE.k, SCENE.c0, SCENE.zc, lambda: d.gram).hessian(phi, solved.nu[0])
    assert abs(a.forms.hessian(0) - H).max() < 1e-13 * abs(H).max()


def _mass(a, m):
    """M_m = t_m int psi^2 r dr dz as a sparse matrix, psi = r^m chi_h."""
    o = a.forms.ops
    return o.B0.T @ scipy.sparse.diags((1.0 if m == 0 else 0.5) * o.w * o.r ** (2 * m)) @ o.B0


def _dense(a, m, constraints):
    """Dense H_m, M_m (one rank: local numbers are global ones), restricted for m = 0
    to the null space of the first `constraints` constraint gradients, and the basis."""
    H, M = a.forms.hessian(m).toarray(), _mass(a, m).toarray()
    if m:
        return H, M, np.eye(len(H))
    C = np.column_stack([c.getArray(readonly=True) for c in a.C[:constraints]])
    Z = scipy.linalg.null_space(C.T)
    return Z.T @ H @ Z, Z.T @ M @ Z, Z


@pytest.mark.parametrize('m', [0, 1, 2])
def test_index_and_eigenpairs_match_dense_linear_algebra(analysis, m):
    a = analysis
    H, M, Z = _dense(a, m, len(a.C))
    dense = scipy.linalg.eigh(H, M, eigvals_only=True)
    s = a.spectrum(m)
    assert s.index == np.count_nonzero(dense < 0)
    assert len(s.eigenvalues) == a.nev
    np.testing.assert_allclose(s.eigenvalues, dense[:a.nev], rtol=1e-8, atol=1e-10 * dense[-1])
    Hm, Mm = a.forms.hessian(m), _mass(a, m)
    for value, chi in zip(s.eigenvalues, s.vectors):
        c = chi.getArray(readonly=True)
        assert c @ (Mm @ c) == pytest.approx(1.0, rel=1e-8)            # M_m-normalized
        if m == 0:                                                      # on the tangent space
            C = np.column_stack([g.getArray(readonly=True) for g in a.C])
            assert np.abs(C.T @ c).max() < 1e-10 * np.abs(C).sum(axis=0).max() * np.abs(c).max()
        residual = Z.T @ (Hm @ c - value * (Mm @ c))
        assert np.linalg.norm(residual) < 1e-6 * np.linalg.norm(Hm @ c)


def test_negative_eigenvalues_far_from_zero_are_all_found(solved):
    """A tension far above the state's makes the area term -nu_A Hess A dominate: many
    negative eigenvalues, the lowest far from the first shift 0, which must move."""
    from pfmembrane.parallel.problem import Problem
    problem = Problem(solved.grid, SCENE, EPS, 'modes_test_')
    a = problem.modes(solved.phi, 40 * solved.nu[0])
    try:
        H, M, _ = _dense(a, 3, 0)
        dense = scipy.linalg.eigh(H, M, eigvals_only=True)
        s = a.spectrum(3)
    finally:
        problem.close()
    assert s.index == np.count_nonzero(dense < 0) > a.nev
    np.testing.assert_allclose(s.eigenvalues, dense[:a.nev], rtol=1e-8)


def test_the_moment_constraint_removes_the_axial_translation(analysis):
    """Without M = 0 the tangent space of A and V holds the translation along the axis,
    phi_z, as a near-null mode; with it the m = 0 spectrum starts far above 0."""
    a = analysis
    H, M, Z = _dense(a, 0, 2)
    values, vectors = scipy.linalg.eigh(H, M, subset_by_index=[0, 1])
    psi, uz, w = a.forms.field(Z @ vectors[:, 0], 0), a.forms.uz, a.forms.ops.w
    assert abs(np.dot(w * psi, uz)) / np.sqrt(np.dot(w * psi, psi) * np.dot(w * uz, uz)) > 0.99
    assert abs(values[0]) < 5e-3 * values[1]        # measured 2e-3 on 1,511 nodes
    s = a.spectrum(0)
    assert s.index == 0 and s.eigenvalues[0] > 100 * abs(values[0])   # measured 270


@pytest.fixture(scope='module')
def finer(comm):
    return _solved(comm, 3000)


def _rigid_modes(result):
    """The m = 1 spectrum of `result`, the fields of its two lowest modes and of the
    rigid motions at the quadrature points away from the walls, with the weights there."""
    from pfmembrane.parallel.problem import Problem
    problem = Problem(result.grid, SCENE, EPS, 'modes_test_')
    a = problem.modes(result.phi, result.nu[0])
    try:
        s = a.spectrum(1)
        o = a.forms.ops
        inner = (o.r < SCENE.box[0] - 0.3) & (o.z > 0.3) & (o.z < SCENE.box[1] - 0.3)
        modes = np.array([a.field(chi, 1)[inner] for chi in s.vectors[:2]])
        motions = [f[inner] / np.abs(f).max() for f in a.forms.rigid(1)]
    finally:
        problem.close()
    return s, modes, motions, o.w[inner]


def test_the_lowest_m1_modes_are_the_lateral_translation_and_rotation(solved, finer):
    """The two lowest m = 1 eigenvalues are those of the rigid motions that move the
    vesicle off its axis, d phi / dx = phi_r cos(theta) and the rotation about y: below
    1e-3 of the first elastic one and smaller on the finer grid, their modes spanning
    phi_r (and the rotation's field) pointwise, away from the walls. At the walls phi_h
    relaxes from its bulk value -1 + nu_V / (2 k_bulk) ~ -1.007 (k_bulk = 2 cE W'^2 -
    nu_A f_A 2 / eps) to the imposed -1, a layer that does not move with the vesicle.
    (With the default support cut-off 1e-6 they stop falling at ~1e-2 beyond 3,000
    nodes: runs/modes/README.md.)"""
    largest = []
    for result, error in ((solved, 5e-3), (finer, 5e-4)):   # measured 2.6e-3, 2.0e-4
        s, modes, motions, w = _rigid_modes(result)
        assert np.all(s.rigid[:2] > 0.99) and np.all(s.rigid[2:] < 1e-3)
        largest.append(np.abs(s.eigenvalues[:2]).max())
        assert largest[-1] < 1e-3 * s.eigenvalues[2]
        for motion in motions:
            coef = np.linalg.solve((modes * w) @ modes.T, modes @ (w * motion))
            assert np.abs(motion - coef @ modes).max() < error
    assert largest[1] < 0.5 * largest[0]


def test_stability_records_the_index_per_m_that_the_checkpoint_keeps(solved, tmp_path):
    """pf.stability: per m the index of `spectrum` without the rigid motions, the lowest
    non-rigid eigenvalue, both written by `save` and read back."""
    from pfmembrane.kernels.azimuthal import RIGID
    spectra = pf.stability(solved, modes=2)
    assert [s.m for s in spectra] == [0, 1, 2]
    rigid = [(s.rigid > RIGID) for s in spectra]
    assert list(solved.attrs['index_m']) == [
        s.index - np.count_nonzero(r & (s.eigenvalues < 0)) for s, r in zip(spectra, rigid)]
    assert list(solved.attrs['index_m']) == [0, 0, 1]          # the oblate v = 0.8: m = 2
    np.testing.assert_allclose(solved.attrs['lowest_m'],
                               [s.eigenvalues[~r].min() for s, r in zip(spectra, rigid)])
    assert all(len(chi) == len(solved.nodes) for s in spectra for chi in s.vectors)
    again = pf.read(solved.save(tmp_path / 'modes.h5').path)
    assert list(again.attrs['index_m']) == [0, 0, 1]
    np.testing.assert_array_equal(again.attrs['lowest_m'], solved.attrs['lowest_m'])


def test_the_run_line_reports_and_checkpoints_the_index(pfm, tmp_path):
    out = tmp_path / 'm.h5'
    run = pfm('-options_file', 'options/discocyte.opts', '-pf_nodes', '1500', '-pf_eps',
              f'{EPS:g}', '-pf_modes', '2', '-pf_output', out, n=1)
    assert run.returncode == 0, run.stderr
    line = [x for x in run.stdout.splitlines() if x.startswith('stability:')]
    assert line and line[0].startswith('stability: index per m = 0..2: 0 0 1, lowest')
    assert 'UNSTABLE to m = 2' in line[0]
    assert list(pf.read(out).attrs['index_m']) == [0, 0, 1]
