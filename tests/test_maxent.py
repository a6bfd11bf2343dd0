"""Tests for the local max-ent approximants."""

import numpy as np
import pytest
import scipy.sparse
from scipy.interpolate import LinearNDInterpolator
from scipy.spatial import Delaunay

from pfmembrane.kernels.maxent import interpolate, local_maxent, support_radius

BOX = np.array([1.0, 1.5])
GAMMAS = (0.6, 0.8, 1.0, 2.0, 4.0, 6.0)


def jittered_lattice(h=1 / 12, jitter=0.1, seed=0):
    """Triangular lattice in BOX with nodes on all edges, interior jittered.

    A triangular lattice has a well-defined Delaunay triangulation, unlike a
    square one whose cells are cocircular.
    """
    rng = np.random.default_rng(seed)
    nz = int(round(BOX[1] / (h * np.sqrt(3) / 2)))
    x = np.linspace(0.0, BOX[0], int(round(BOX[0] / h)) + 1)
    rows = []
    for k, z in enumerate(np.linspace(0.0, BOX[1], nz + 1)):
        xs = np.r_[0.0, 0.5 * (x[:-1] + x[1:]), BOX[0]] if k % 2 else x
        rows.append(np.column_stack([xs, np.full_like(xs, z)]))
    nodes = np.concatenate(rows)
    inside = np.all((nodes > 0) & (nodes < BOX), axis=1)
    nodes[inside] += rng.uniform(-jitter, jitter, (inside.sum(), 2)) * h
    return nodes


def graded_grid(n=14, ratio=4.0, jitter=0.15, seed=1):
    """Tensor grid in BOX whose spacing grows by `ratio` along each axis."""
    rng = np.random.default_rng(seed)
    s = (ratio ** np.linspace(0.0, 1.0, n) - 1) / (ratio - 1)
    r, z = np.meshgrid(s * BOX[0], s * BOX[1], indexing="ij")
    nodes = np.column_stack([r.ravel(), z.ravel()])
    inside = np.all((nodes > 0) & (nodes < BOX), axis=1)
    h = spacing(nodes)
    nodes[inside] += (rng.uniform(-jitter, jitter, (inside.sum(), 2))
                      * h[inside, None])
    return nodes


def spacing(nodes):
    """Mean distance of each node to its Delaunay neighbours."""
    indptr, neighbours = Delaunay(nodes).vertex_neighbor_vertices
    owner = np.repeat(np.arange(len(nodes)), np.diff(indptr))
    dist = np.linalg.norm(nodes[neighbours] - nodes[owner], axis=1)
    return np.bincount(owner, dist) / np.diff(indptr)


def random_points(n, seed=2):
    """Uniformly distributed points in BOX."""
    return np.random.default_rng(seed).uniform(0.0, BOX, (n, 2))


def dense(basis, values, nnodes):
    """Dense (npts, nnodes) matrix of one field of `basis`."""
    return scipy.sparse.csr_matrix(
        (values, basis.indices, basis.indptr),
        shape=(len(basis.indptr) - 1, nnodes)).toarray()


def point_sums(basis, values):
    """Sum over the nodes of each point."""
    return np.add.reduceat(values, basis.indptr[:-1], axis=0)


def check_identities(basis, nodes, points, hessians=True, rtol=1e-10):
    """Reproduction of constants and linear functions, with derivatives.

    Derivative sums are compared with the largest derivative of the point,
    or with 1/h and 1/h^2 where the derivatives happen to be smaller. In the
    interior the measured errors are below 1e-13.
    """
    xa = nodes[basis.indices]
    assert np.all(basis.p >= 0)
    assert np.allclose(point_sums(basis, basis.p), 1, rtol=0, atol=1e-10)
    assert np.allclose(point_sums(basis, basis.p[:, None] * xa), points,
                       rtol=0, atol=1e-10)

    h = spacing(nodes).min()
    g_scale = np.maximum(np.maximum.reduceat(
        np.abs(basis.dp).max(axis=1), basis.indptr[:-1]), 1 / h)
    g_sum = point_sums(basis, basis.dp)
    g_lin = point_sums(basis, basis.dp[:, :, None] * xa[:, None, :])
    assert np.all(np.abs(g_sum).max(axis=1) <= 1e-10 * g_scale)
    assert np.allclose(g_lin, np.eye(2), rtol=0, atol=1e-10)
    if hessians:
        h_scale = np.maximum(np.maximum.reduceat(
            np.abs(basis.ddp).max(axis=1), basis.indptr[:-1]), 1 / h ** 2)
        h_sum = point_sums(basis, basis.ddp)
        h_lin = point_sums(basis, basis.ddp[:, :, None] * xa[:, None, :])
        assert np.all(np.abs(h_sum).max(axis=1) <= rtol * h_scale)
        assert np.all(np.abs(h_lin).max(axis=(1, 2)) <= rtol * h_scale)


@pytest.mark.parametrize("grid", [jittered_lattice, graded_grid])
@pytest.mark.parametrize("gamma", [0.8, 4.0])
def test_reproduction_and_derivative_identities(grid, gamma):
    nodes = grid()
    # Points on nodes, away from the hull boundary where p is only C^0.
    inside = np.all((nodes > 0) & (nodes < BOX), axis=1)
    points = np.concatenate([random_points(500), nodes[inside][::5]])
    basis = local_maxent(points, nodes, gamma / spacing(nodes) ** 2)
    check_identities(basis, nodes, points)


def test_neighbours_are_exactly_the_nodes_within_the_support_radius():
    nodes = graded_grid()
    beta = 0.8 / spacing(nodes) ** 2
    points = np.concatenate([random_points(300), nodes[:20]])
    basis = local_maxent(points, nodes, beta, derivatives=0)

    dist = np.linalg.norm(points[:, None] - nodes[None], axis=2)
    expected = np.exp(-beta * dist ** 2) >= 1e-6
    assert np.array_equal(expected, dist <= support_radius(beta, 1e-6))
    found = dense(basis, np.ones_like(basis.p), len(nodes)) > 0
    assert np.array_equal(found, expected)
    for start, stop in zip(basis.indptr[:-1], basis.indptr[1:]):
        assert np.all(np.diff(basis.indices[start:stop]) > 0)


@pytest.mark.parametrize("gamma", [0.8, 3.0])
def test_derivatives_match_finite_differences_on_graded_grid(gamma):
    nodes = graded_grid()
    h = spacing(nodes)
    assert h.max() / h.min() > 3.5       # beta_a genuinely varies
    beta = gamma / h ** 2
    points = random_points(40, seed=3) * 0.8 + 0.1 * BOX
    # A negligible cut-off keeps the neighbour sets of the shifted points
    # equal, so that the difference quotients see a smooth function.
    cutoff = 1e-30
    basis = local_maxent(points, nodes, beta, cutoff)
    grad = [dense(basis, basis.dp[:, i], len(nodes)) for i in range(2)]
    hess = [dense(basis, basis.ddp[:, k], len(nodes)) for k in range(3)]
    hess = [[hess[0], hess[1]], [hess[1], hess[2]]]

    # Measured relative errors: at most 1e-10 (gamma 0.8), 7e-9 (gamma 3).
    step = 1e-5 * h.min()
    for j in range(2):
        shift = np.zeros(2)
        shift[j] = step
        plus = local_maxent(points + shift, nodes, beta, cutoff)
        minus = local_maxent(points - shift, nodes, beta, cutoff)
        fd = (dense(plus, plus.p, len(nodes))
              - dense(minus, minus.p, len(nodes))) / (2 * step)
        assert np.abs(fd - grad[j]).max() <= 1e-7 * np.abs(grad[j]).max()
        for i in range(2):
            fd = (dense(plus, plus.dp[:, i], len(nodes))
                  - dense(minus, minus.dp[:, i], len(nodes))) / (2 * step)
            exact = hess[i][j]
            assert np.abs(fd - exact).max() <= 1e-7 * np.abs(exact).max()


@pytest.mark.parametrize("grid", [jittered_lattice, graded_grid])
@pytest.mark.parametrize("gamma", GAMMAS)
def test_newton_converges_at_corners_and_edges(grid, gamma):
    nodes = grid()
    beta = gamma / spacing(nodes) ** 2
    corners = np.array([[0, 0], [1, 0], [0, 1], [1, 1]]) * BOX
    inward = np.sign(0.5 * BOX - corners)
    t = np.linspace(0.0, 1.0, 9)[1:-1, None]
    edges = np.concatenate([t * [BOX[0], 0], t * [BOX[0], 0] + [0, BOX[1]],
                            t * [0, BOX[1]], t * [0, BOX[1]] + [BOX[0], 0]])
    normals = np.repeat([[0, 1], [0, -1], [1, 0], [-1, 0]], len(t), axis=0)
    on_boundary = np.concatenate([corners, edges])
    near_boundary = np.concatenate([corners + 1e-9 * inward,
                                    edges + 1e-9 * normals])

    basis = local_maxent(on_boundary, nodes, beta)
    check_identities(basis, nodes, on_boundary, hessians=False)
    # The hull vertices are interpolated exactly.
    corner_nodes = [np.argmin(np.linalg.norm(nodes - c, axis=1))
                    for c in corners]
    values = dense(basis, basis.p, len(nodes))
    assert np.allclose(values[np.arange(4), corner_nodes], 1, atol=1e-10)

    # Second derivatives lose accuracy like 1e-16 h / d, d = 1e-9 here;
    # measured up to 6e-8.
    basis = local_maxent(near_boundary, nodes, beta)
    check_identities(basis, nodes, near_boundary, rtol=1e-6)


def test_large_gamma_approaches_delaunay_interpolant():
    # A constant beta, since the limit of per-node beta_a is a weighted
    # (regular) triangulation rather than the Delaunay one.
    h = 1 / 12
    nodes = jittered_lattice(h)
    points = random_points(3000, seed=4)
    tri = Delaunay(nodes)
    simplex = tri.find_simplex(points)
    affine = tri.transform[simplex]
    bary = np.einsum("cij,cj->ci", affine[:, :2], points - affine[:, 2])
    hats = np.zeros((len(points), len(nodes)))
    np.put_along_axis(hats, tri.simplices[simplex],
                      np.column_stack([bary, 1 - bary.sum(axis=1)]), axis=1)

    def u(x):
        return np.sin(3 * x[:, 0]) * np.cos(2 * x[:, 1]) + x[:, 0] ** 2

    linear = LinearNDInterpolator(nodes, u(nodes))(points)
    linear_error = np.sqrt(np.mean((linear - u(points)) ** 2))

    hat_distance, value_distance = [], []
    for gamma in (0.8, 2.0, 4.0, 6.0):
        basis = local_maxent(points, nodes, gamma / h ** 2, derivatives=0)
        p = dense(basis, basis.p, len(nodes))
        hat_distance.append(np.abs(p - hats).sum(axis=1).mean())
        value_distance.append(np.sqrt(np.mean(
            (interpolate(basis, u(nodes)) - linear) ** 2)) / linear_error)
    # Measured: hat distances 1.10, 0.52, 0.14, 0.050; value distances,
    # relative to the linear interpolation error, 3.3, 0.93, 0.23, 0.11.
    assert np.all(np.diff(hat_distance) < 0)
    assert np.all(np.diff(value_distance) < 0)
    assert hat_distance[2] < 0.2 and hat_distance[3] < 0.08
    assert value_distance[2] < 0.35 and value_distance[3] < 0.2


@pytest.mark.parametrize("grid", [jittered_lattice, graded_grid])
def test_cutoff_perturbs_values_by_about_the_cutoff(grid):
    nodes = grid()
    beta = 0.8 / spacing(nodes) ** 2
    points = np.concatenate([random_points(1000, seed=5), [[0, 0], BOX]])
    coarse = local_maxent(points, nodes, beta, cutoff=1e-6, derivatives=0)
    fine = local_maxent(points, nodes, beta, cutoff=1e-9, derivatives=0)
    assert len(fine.p) > 1.3 * len(coarse.p)
    for basis in (coarse, fine):
        assert np.allclose(interpolate(basis, nodes), points, atol=1e-10)
    change = np.abs(dense(coarse, coarse.p, len(nodes))
                    - dense(fine, fine.p, len(nodes))).max()
    # Measured 1.3e-6 (lattice) and 1.2e-6 (graded).
    assert 1e-7 < change < 3e-6


def test_interpolate_matches_dense_product_and_chunking():
    nodes = jittered_lattice()
    beta = 0.8 / spacing(nodes) ** 2
    points = random_points(50, seed=6)
    values = np.random.default_rng(7).normal(size=(len(nodes), 3))
    basis = local_maxent(points, nodes, beta)
    expected = dense(basis, basis.p, len(nodes)) @ values
    assert np.allclose(interpolate(basis, values), expected, atol=1e-14)
    assert np.allclose(interpolate(basis, values[:, 0]), expected[:, 0],
                       atol=1e-14)

    # Chunks differ in padding, hence in summation order.
    chunked = local_maxent(points, nodes, beta, chunk=7)
    assert np.array_equal(basis.indptr, chunked.indptr)
    assert np.array_equal(basis.indices, chunked.indices)
    for a, b in zip(basis[2:], chunked[2:]):
        assert np.allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(a).max())


def test_derivative_orders_and_empty_input():
    nodes = jittered_lattice()
    beta = 0.8 / spacing(nodes) ** 2
    points = random_points(5)
    assert local_maxent(points, nodes, beta, derivatives=0).dp is None
    first = local_maxent(points, nodes, beta, derivatives=1)
    assert first.dp.shape == (len(first.p), 2) and first.ddp is None
    empty = local_maxent(np.zeros((0, 2)), nodes, beta)
    assert empty.indptr.tolist() == [0]
    assert empty.p.shape == (0,) and empty.ddp.shape == (0, 3)


def test_invalid_points_raise():
    nodes = jittered_lattice()
    h = spacing(nodes)
    beta = 0.8 / h ** 2
    with pytest.raises(ValueError, match="convex hull"):
        local_maxent([[0.5, -1e-6]], nodes, beta)
    with pytest.raises(ValueError, match="no neighbouring nodes"):
        local_maxent([[5.0, 5.0]], nodes, beta)
    # With a tiny support only one node covers the second point: inside the
    # hull of all nodes but not of its neighbours, so Newton cannot converge.
    centre = np.argmin(np.linalg.norm(nodes - 0.5 * BOX, axis=1))
    points = [nodes[centre], nodes[centre] + [0.2 * h[centre], 0]]
    with pytest.raises(RuntimeError, match="point 1 at"):
        local_maxent(points, nodes, beta, cutoff=0.9, chunk=1)
