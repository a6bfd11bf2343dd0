"""The topology of a level set: spheres from the axis to the axis, tori off
it, pieces through the box; a comparison with the sharp shape only for one
sphere."""
from dataclasses import replace

import numpy as np
import pytest

from pfmembrane.analysis import levelset
from pfmembrane.io import checkpoint
from pfmembrane.kernels import nodes as nodesets

BOX = (1.5, 2.0)


def field_checkpoint(path, distance, eps=0.05, n=3000, **scene):
    """phi = tanh(d / (sqrt2 eps)) for a signed distance d(r, z) > 0 inside; `scene`
    overrides attributes (c0, k, ...)."""
    nodes = nodesets.uniform(BOX, n)
    phi = np.tanh(distance(nodes[:, 0], nodes[:, 1]) / (np.sqrt(2.0) * eps))
    phi[nodesets.dirichlet_mask(nodes, BOX)] = -1.0
    attrs = {"energy": 10.0, "area": 1.0, "volume": 0.1, "moment": 0.0, "eps": eps, "k": 1.0,
             "c0": 0.0, "gamma": 0.8, "nu_area": 0.0, "nu_volume": 0.0, "converged": 1,
             "wall_time": 1.0, "box": BOX, "cutoff": 1e-6, "radius": 0.4,
             "reduced_volume": 0.8, "branch": "oblate"}
    attrs.update(scene)
    checkpoint.write(path, nodes, phi, attrs)
    return checkpoint.read(path)


def sphere(r, z, zc=1.0, radius=0.4):
    return radius - np.hypot(r, z - zc)


def ring(r, z, centre=0.5, tube=0.15):
    return tube - np.hypot(r - centre, z - 1.0)


@pytest.mark.parametrize('distance, label, genus', [
    (sphere, '1 sphere', 0),
    (ring, '1 torus', 1),
    (lambda r, z: np.maximum(sphere(r, z, 0.65, 0.25), sphere(r, z, 1.35, 0.25)), '2 spheres', 0),
    (lambda r, z: np.maximum(sphere(r, z, 1.0, 0.2), ring(r, z, 0.7, 0.12)),
     '1 sphere + 1 torus', 1),
])
def test_the_level_set_of_a_field_has_its_topology(tmp_path, distance, label, genus):
    ckpt = field_checkpoint(tmp_path / 'f.h5', distance)
    found = levelset.topology(levelset.level_set(ckpt), BOX)
    assert found['label'] == label and found['tori'] == genus
    assert found['components'] == sum(int(part.split()[0]) for part in label.split(' + '))


def test_a_piece_through_the_box_is_open():
    arc = np.column_stack([np.linspace(0.2, 1.5, 20), np.full(20, 1.0)])
    assert levelset.topology([arc], BOX)['label'] == '1 open piece'


def test_a_torus_is_not_compared_with_the_sharp_sphere(tmp_path):
    ckpt = field_checkpoint(tmp_path / 'f.h5', ring)
    with pytest.raises(ValueError, match='1 torus'):
        levelset.compare(ckpt)


@pytest.mark.slow  # two solves
def test_a_solve_that_changes_topology_says_so():
    # The torus at v 0.8 and eps 0.04 keeps its hole; at v 0.85 its hole closes: a
    # sphere. A fresh start knows its own topology, a restart its start's.
    import sys
    import pfmembrane as pf
    comm = pf.api.petsc(sys.argv[:1]).COMM_SELF
    scene = pf.Scene(reduced_volume=0.8, branch='torus', box=(0.8, 1.0), symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=1633, comm=comm)
    torus = pf.solve(scene, grid, 0.04, checks=True)
    assert torus.attrs['start_topology'] == torus.attrs['topology'] == '1 torus'
    with pytest.warns(UserWarning, match='changed topology: the start was 1 torus, phi_h = 0 '
                      'is 1 sphere'):
        closed = pf.solve(replace(scene, reduced_volume=0.85), grid, 0.04, start=torus,
                          checks=True)
    assert closed.converged and closed.attrs['topology'] == '1 sphere'
