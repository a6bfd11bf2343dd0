"""Node sets, quadrature exactness, the initial spheroids."""
import numpy as np
import pytest

from pfmembrane.kernels import nodes, quadrature
from pfmembrane.kernels.initial import rescaled_phi, spheroid_area, spheroid_axes

BOX = (1.5, 2.0)


@pytest.mark.parametrize("n, hbar", [(6124, 0.024), (12271, 0.017),
                                     pytest.param(24597, 0.012, marks=pytest.mark.slow)])
def test_uniform_grids_match_the_paper(n, hbar):
    x = nodes.uniform(BOX, n)
    assert abs(len(x) - n) < 0.01 * n
    labels = nodes.edge_labels(x, BOX)
    for edge in (nodes.AXIS, nodes.OUTER, nodes.BOTTOM, nodes.TOP):
        assert (labels & edge).sum() > 10
    tri = quadrature.triangulate(x)
    e = np.unique(np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), 1), axis=0)
    d = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)
    assert abs(d.mean() - hbar) < 0.05 * hbar          # Table 1's mean spacing
    assert np.array_equal(x, nodes.uniform(BOX, n))   # deterministic


@pytest.mark.parametrize("degree", quadrature.DEGREES)
def test_quadrature_exact_on_polynomials(degree):
    x = nodes.uniform(BOX, 800)
    pts, w = quadrature.rule(quadrature.cells(x, quadrature.triangulate(x)), degree,
                             axisymmetric=False)
    r, z = pts.T
    for i in range(degree + 1):
        for j in range(degree + 1 - i):
            exact = BOX[0] ** (i + 1) / (i + 1) * BOX[1] ** (j + 1) / (j + 1)
            assert abs(np.dot(w, r ** i * z ** j) - exact) < 1e-12 * max(1.0, exact)


def test_box_volume():
    x = nodes.uniform(BOX, 2000)
    _, w = quadrature.rule(quadrature.cells(x, quadrature.triangulate(x)), 4)
    assert abs(w.sum() - np.pi * BOX[0] ** 2 * BOX[1]) < 1e-12 * w.sum()


def test_axis_mirrors_are_reflections():
    x = nodes.uniform(BOX, 500)
    beta = np.full(len(x), 3.0)
    aug, baug, owner = nodes.with_mirrors(x, beta, 0.2)
    extra = aug[len(x):]
    assert np.all(extra[:, 0] < 0) and np.allclose(np.abs(extra), x[owner[len(x):]])
    assert not np.any(x[owner[len(x):], 0] == 0.0)  # axis nodes are their own mirrors


def test_plane_mirrors_reflect_the_nodes_and_the_axis_mirrors():
    x = nodes.uniform(BOX, 500, half=True)
    plane, radius = BOX[1] / 2, 0.2
    aug, baug, owner = nodes.with_mirrors(x, np.arange(len(x), dtype=float), radius, plane)
    assert np.array_equal(baug, owner)  # every image carries its original's beta
    image = aug[len(x):]
    original = x[owner[len(x):]]
    np.testing.assert_allclose(np.abs(image[:, 0]), original[:, 0])
    below = image[:, 1] < plane
    np.testing.assert_allclose(2 * plane - image[below, 1], original[below, 1])
    # Nodes near the corner (0, plane) have three images: r, z and both flipped.
    near = (x[:, 0] > 0) & (x[:, 0] < radius) & (x[:, 1] > plane) & (x[:, 1] < plane + radius)
    counts = np.bincount(owner, minlength=len(x))
    assert near.any() and np.all(counts[near] == 4)
    assert np.all(counts[x[:, 1] == plane] <= 2)  # nodes on the plane are their own images


def test_half_lattice_row_lies_on_the_plane():
    # dz * rows / 2 misses Zb / 2 by an ulp in this box (the prolate's at v 0.85, c0 1,
    # eps 0.02): a row off the plane by 1e-16 left 23 nodes without neighbours (h NaN)
    box = (0.43, 1.63)
    x = nodes.uniform(box, 6197, half=True)
    plane = box[1] / 2
    assert x[:, 1].min() == plane and np.sum(x[:, 1] == plane) > 10
    assert np.all(np.isfinite(nodes.nodal_spacing(x, plane=plane)))


def test_unfold_mirrors_a_half_box_solution():
    x = nodes.uniform(BOX, 500, half=True)
    phi = x[:, 1] ** 2
    full, values = nodes.unfold(x, phi, BOX[1] / 2)
    assert len(full) == 2 * len(x) - np.sum(x[:, 1] == BOX[1] / 2)
    # phi = z^2 above the plane, its mirror image (Zb - z)^2 below.
    np.testing.assert_allclose(values, np.maximum(full[:, 1], BOX[1] - full[:, 1]) ** 2)


def test_spheroids_have_the_scene_area_and_volume():
    R = 0.4
    A, V = 4 * np.pi * R ** 2, 0.8 * 4 / 3 * np.pi * R ** 3
    for branch, (a_ref, c_ref) in {'oblate': (0.4987, 0.2059), 'prolate': (0.2637, 0.7362)}.items():
        a, c = spheroid_axes(A, V, branch)
        assert abs(a - a_ref) < 1e-4 and abs(c - c_ref) < 1e-4
        assert abs(spheroid_area(a, c) / A - 1) < 1e-10
        assert abs(4 / 3 * np.pi * a * a * c / V - 1) < 1e-10
    with pytest.raises(ValueError):
        spheroid_axes(A, 1.1 * 4 / 3 * np.pi * R ** 3, 'oblate')


def test_spacing_smoothing_removes_scatter_and_keeps_a_lattice():
    x = nodes.uniform(BOX, 2000)
    inner = nodes.edge_labels(x, BOX) == 0
    raw, smooth = nodes.nodal_spacing(x), nodes.nodal_spacing(x, smoothing=3)
    far = inner & (x[:, 0] > 0.2) & (x[:, 0] < 1.3) & (x[:, 1] > 0.2) & (x[:, 1] < 1.8)
    assert np.allclose(smooth[far], raw[far], rtol=1e-12)   # constant on the lattice
    rng = np.random.default_rng(0)
    y = x.copy()
    y[inner] += 0.15 * raw.mean() * rng.standard_normal((inner.sum(), 2))
    raw, smooth = nodes.nodal_spacing(y), nodes.nodal_spacing(y, smoothing=3)
    assert abs(smooth.mean() / raw.mean() - 1) < 0.01           # the scale is kept
    assert smooth[far].std() < 0.5 * raw[far].std()              # the scatter is not


def test_rescaled_phi_narrows_the_tanh_profile_about_its_zero():
    d = np.linspace(-0.2, 0.2, 81)
    phi = np.tanh(d / (np.sqrt(2.0) * 0.015))
    phi[[0, -1]] = [-1.0, 1.0004]        # an imposed value and an overshoot

    out = rescaled_phi(phi, 0.015, 0.01)

    assert np.allclose(out[1:-1], np.tanh(d[1:-1] / (np.sqrt(2.0) * 0.01)), atol=1e-12)
    assert out[0] == -1.0 and out[-1] == 1.0004
    assert np.array_equal(rescaled_phi(phi, 0.01, 0.01), phi)


@pytest.mark.parametrize('parts', [2, 3, 4, 7])
def test_bisection_cuts_across_the_longer_side_into_parts_of_equal_size(parts):
    from pfmembrane.parallel.partition import bisection
    xy = nodes.uniform((0.75, 2.0), 1500)
    part = bisection(xy, parts)
    counts = np.bincount(part, minlength=parts)
    assert len(counts) == parts and np.ptp(counts) <= 1
    if parts == 2:  # one straight cut across z
        assert xy[part == 0, 1].max() <= xy[part == 1, 1].min()


def test_cells_tile_the_half_box_with_no_nodes_on_the_plane():
    x = nodes.uniform(BOX, 800, half=True)
    plane = BOX[1] / 2
    rng = np.random.default_rng(1)
    off = (x[:, 1] == plane) & (x[:, 0] > 0) & (x[:, 0] < BOX[0])
    x[off, 1] += rng.uniform(0.2, 0.5, off.sum()) * 0.06   # lift the plane's row
    cells = quadrature.cells(x, quadrature.triangulate(x), plane)
    assert cells[:, :, 1].min() == plane
    pts, w = quadrature.rule(cells, 4, axisymmetric=False)
    for i, j in [(0, 0), (1, 2), (3, 1)]:
        exact = BOX[0] ** (i + 1) / (i + 1) * (BOX[1] ** (j + 1) - plane ** (j + 1)) / (j + 1)
        assert abs(np.dot(w, pts[:, 0] ** i * pts[:, 1] ** j) - exact) < 1e-12 * exact
    # With the row on the plane the cells are the nodes' own Delaunay triangles.
    y = nodes.uniform(BOX, 800, half=True)
    tri = quadrature.triangulate(y)
    np.testing.assert_array_equal(quadrature.cells(y, tri, plane), y[tri])


def test_cells_tile_the_box_with_no_nodes_on_the_axis():
    # Adapted nodes leave the axis (`cvt.lloyd`): without feet on it, the
    # triangles next to it would be slivers from one corner to the other.
    x = nodes.uniform(BOX, 800)
    rng = np.random.default_rng(4)
    off = (x[:, 0] == 0) & (x[:, 1] > 0) & (x[:, 1] < BOX[1])
    x[off, 0] += rng.uniform(0.2, 0.5, off.sum()) * 0.06    # lift the axis's nodes
    cells = quadrature.cells(x, quadrature.triangulate(x))
    assert cells[:, :, 0].min() == 0.0
    pts, w = quadrature.rule(cells, 4, axisymmetric=False)
    for i, j in [(0, 0), (1, 2), (3, 1)]:
        exact = BOX[0] ** (i + 1) / (i + 1) * BOX[1] ** (j + 1) / (j + 1)
        assert abs(np.dot(w, pts[:, 0] ** i * pts[:, 1] ** j) - exact) < 1e-12 * exact
    edges = np.linalg.norm(cells - np.roll(cells, 1, axis=1), axis=2).max(axis=1)
    assert edges.max() < 3 * np.median(nodes.nodal_spacing(x))
    # On a lattice, whose even rows start on the axis, the cells are the
    # nodes' own Delaunay triangles.
    y = nodes.uniform(BOX, 800)
    tri = quadrature.triangulate(y)
    np.testing.assert_array_equal(quadrature.cells(y, tri), y[tri])


def test_spacing_near_the_mirrors_is_continuous_in_the_nodes():
    # Nodes and their images are cocircular in pairs; h_a must not depend on
    # which diagonal Qhull takes, so 1e-10 in the nodes gives ~1e-10 in h_a.
    x = nodes.uniform(BOX, 800, half=True)
    plane = BOX[1] / 2
    rng = np.random.default_rng(2)
    x[x[:, 1] == plane, 1] += 0.01                          # no row on the plane
    inner = (x[:, 0] > 0) & (x[:, 0] < BOX[0]) & (x[:, 1] < BOX[1])
    x[inner] += rng.uniform(-3e-3, 3e-3, (inner.sum(), 2))
    y = x.copy()
    y[inner] += rng.uniform(-1e-10, 1e-10, (inner.sum(), 2))
    for mirror in (None, plane):
        hx, hy = nodes.nodal_spacing(x, plane=mirror), nodes.nodal_spacing(y, plane=mirror)
        assert np.abs(hx - hy).max() < 1e-8
    # On a lattice the mirrors' nodes keep the spacing of the others.
    lat = nodes.uniform(BOX, 800, half=True)
    h = nodes.nodal_spacing(lat, plane=plane)
    away = (lat[:, 0] < BOX[0] - 0.2) & (lat[:, 1] < BOX[1] - 0.2)
    on = away & ((lat[:, 1] == plane) | (lat[:, 0] == 0.0))
    assert np.abs(h[on] / np.median(h[away]) - 1.0).max() < 0.02


def test_a_spacing_floor_gives_the_finest_nodes_one_locality():
    from pfmembrane.kernels.basis import locality, spacing_and_locality
    x = nodes.uniform(BOX, 1500)
    inner = nodes.edge_labels(x, BOX) == 0
    x[inner] = x[inner] ** 1.5 / np.array(BOX) ** 0.5       # graded towards the corner
    h, beta = spacing_and_locality(x, 0.8, 3)
    assert np.array_equal(beta, 0.8 / nodes.nodal_spacing(x, smoothing=3) ** 2)
    assert np.array_equal(h, nodes.nodal_spacing(x))            # the raw spacing
    _, floored = spacing_and_locality(x, 0.8, 3, floor=0.3)
    top = floored.max()
    assert np.array_equal(floored, np.minimum(beta, top))       # only the finest change
    assert abs(np.mean(floored == top) - 0.3) < 2 / len(x)       # and share one beta
    assert np.ptp(beta[beta >= top]) > 0.5 * top                # which they did not before
    assert np.array_equal(locality(x, 0.8, 3, floor=0.3), floored)
