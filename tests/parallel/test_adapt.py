"""CVT adaptivity: node count, edges and axis, grading toward the interface, transfer
of phi, and the same grid on every rank count.

Collective: one rank under pytest, two under `mpiexec -n 2`.
"""
import numpy as np
import pytest
from mpi4py import MPI

from pfmembrane.kernels import adapt, maxent, nodes
from pfmembrane.parallel.adapt import relocate
from pfmembrane.kernels.basis import folded_basis, locality

BOX, EPS = (1.0, 1.4), 0.05


def _phi(xy, radius=0.45):
    d = np.hypot(xy[:, 0], xy[:, 1] - 0.7) - radius
    phi = -np.tanh(d / (np.sqrt(2) * EPS))
    phi[nodes.dirichlet_mask(xy, BOX)] = -1.0
    return phi


@pytest.fixture(scope='module')
def relocated():
    xy = nodes.uniform(BOX, 900)
    phi = _phi(xy)
    new, new_phi, info = relocate(MPI.COMM_WORLD, xy, phi, BOX, locality(xy, 0.8, 3), 1e-6, 100.0)
    return xy, phi, new, new_phi, info


def test_nodes_are_kept_and_edges_stay_edges_but_the_axis(relocated):
    # The axis is a mirror of the basis: held on it, its nodes would keep their
    # count where the nodes around them thin out (`cvt.lloyd`).
    xy, _, new, _, _ = relocated
    assert new.shape == xy.shape
    boundary = nodes.OUTER | nodes.BOTTOM | nodes.TOP
    before, after = (nodes.edge_labels(x, BOX) for x in (xy, new))
    assert np.array_equal(before & boundary != 0, after & boundary != 0)
    assert np.array_equal(after & nodes.AXIS != 0, (before & nodes.AXIS != 0) & (before & boundary != 0))
    assert ((new >= 0) & (new <= BOX)).all()


def test_nodes_gather_at_the_interface(relocated):
    _, _, new, _, info = relocated
    h = nodes.nodal_spacing(new)
    d = np.abs(np.hypot(new[:, 0], new[:, 1] - 0.7) - 0.45)
    assert np.median(h[d < EPS]) < 0.5 * np.median(h[d > 4 * EPS])
    assert info['h_min'][1] < 0.6 * info['h_min'][0]


def test_phi_is_the_old_interpolant_at_the_new_nodes(relocated):
    xy, phi, new, new_phi, _ = relocated
    inner = ~nodes.dirichlet_mask(new, BOX)
    basis = folded_basis(new[inner], xy, locality(xy, 0.8, 3), 1e-6, 0)
    assert np.allclose(new_phi[inner], maxent.interpolate(basis, phi), atol=1e-14)
    assert (new_phi[~inner] == -1.0).all()
    # fields linear in z (and even in r, as the axis mirrors make every field) transfer exactly
    assert np.allclose(maxent.interpolate(basis, 0.1 - 0.2 * xy[:, 1]), 0.1 - 0.2 * new[inner, 1],
                       atol=1e-10)


def test_same_grid_on_every_rank_count(relocated, distributed):
    xy, phi, new, _, _ = relocated
    comm = MPI.COMM_WORLD
    one = relocate(MPI.COMM_SELF, xy, phi, BOX, locality(xy, 0.8, 3), 1e-6, 100.0)[0]
    assert np.array_equal(one, new)
    assert all(np.array_equal(other, new) for other in comm.allgather(new))


def test_nodes_along_a_branch_gather_at_every_interface(relocated):
    # A second circle, 0.15 larger: the density is the larger |grad phi_h| of the two.
    xy, phi, alone, alone_phi, _ = relocated
    bigger = _phi(xy, 0.6)
    same = relocate(MPI.COMM_WORLD, xy, phi, BOX, locality(xy, 0.8, 3), 1e-6, 100.0,
                          along=phi[None])
    assert np.array_equal(same[0], alone) and np.array_equal(same[1], alone_phi)
    new, new_phi, _ = relocate(MPI.COMM_WORLD, xy, phi, BOX, locality(xy, 0.8, 3), 1e-6,
                                     100.0, along=bigger[None])
    assert np.array_equal(new_phi, adapt.transfer(xy, phi, locality(xy, 0.8, 3), 1e-6, new, BOX))
    h = nodes.nodal_spacing(new)
    far = np.hypot(new[:, 0], new[:, 1] - 0.7)
    for radius in (0.45, 0.6):
        assert np.median(h[np.abs(far - radius) < EPS / 2]) < 0.7 * np.median(h[far > 0.9])


def test_dilate_takes_the_largest_value_within_the_band():
    r, z = np.linspace(0.0, 1.0, 11), np.linspace(0.0, 2.0, 41)  # steps 0.1 and 0.05
    values = np.zeros((len(z), len(r)))
    values[20, 5], values[10, 0] = 3.0, 2.0  # at (r, z) = (0.5, 1.0) and (0, 0.5)
    assert adapt.dilate(values, r, z, 0.0) is values
    R, Z = np.meshgrid(r, z)
    out = adapt.dilate(values, r, z, 0.25)
    near = np.hypot(R - 0.5, Z - 1.0) <= 0.25 + 1e-12
    axis = np.hypot(R, Z - 0.5) <= 0.25 + 1e-12
    assert (out[near] == 3.0).all() and (out[axis] == 2.0).all()
    assert (out[~near & ~axis] == 0.0).all()


def test_a_band_evens_the_spacing_across_the_interface(relocated):
    # Spacing in rings about the circle: within EPS / 2 of it against 1.5-2 EPS out.
    # Without a band the nodes grade across the interface's tanh profile.
    xy, phi, graded, _, _ = relocated
    flat = relocate(MPI.COMM_WORLD, xy, phi, BOX, locality(xy, 0.8, 3), 1e-6, 100.0,
                          band=2 * EPS)[0]

    def ratio(new):
        h = nodes.nodal_spacing(new)
        d = np.abs(np.hypot(new[:, 0], new[:, 1] - 0.7) - 0.45)
        return np.median(h[(d >= 1.5 * EPS) & (d < 2 * EPS)]) / np.median(h[d < EPS / 2])

    assert ratio(graded) > 1.15 and abs(ratio(flat) - 1) < 0.05
