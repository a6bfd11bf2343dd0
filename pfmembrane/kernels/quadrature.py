"""Background quadrature: Gauss rules on the Delaunay triangles of the nodes.

Weights carry the axisymmetric measure, so sum(w * f) = int_Omega f dOmega =
2 pi int int f r dr dz over the solid of revolution.
"""
import numpy as np
from scipy.spatial import ConvexHull, Delaunay

# Symmetric Gauss rules on the reference triangle (Dunavant): degree ->
# (barycentric points, weights summing to 1).
_RULES = {
    1: ([[1 / 3, 1 / 3, 1 / 3]], [1.0]),
    2: ([[2 / 3, 1 / 6, 1 / 6], [1 / 6, 2 / 3, 1 / 6], [1 / 6, 1 / 6, 2 / 3]], [1 / 3] * 3),
    4: ([[0.108103018168070, 0.445948490915965, 0.445948490915965],
         [0.445948490915965, 0.108103018168070, 0.445948490915965],
         [0.445948490915965, 0.445948490915965, 0.108103018168070],
         [0.816847572980459, 0.091576213509771, 0.091576213509771],
         [0.091576213509771, 0.816847572980459, 0.091576213509771],
         [0.091576213509771, 0.091576213509771, 0.816847572980459]],
        [0.223381589678011] * 3 + [0.109951743655322] * 3),
    5: ([[1 / 3, 1 / 3, 1 / 3],
         [0.059715871789770, 0.470142064105115, 0.470142064105115],
         [0.470142064105115, 0.059715871789770, 0.470142064105115],
         [0.470142064105115, 0.470142064105115, 0.059715871789770],
         [0.797426985353087, 0.101286507323456, 0.101286507323456],
         [0.101286507323456, 0.797426985353087, 0.101286507323456],
         [0.101286507323456, 0.101286507323456, 0.797426985353087]],
        [0.225] + [0.132394152788506] * 3 + [0.125939180544827] * 3),
}
DEGREES = tuple(sorted(_RULES))


def triangulate(nodes):
    """Delaunay triangles (M x 3 vertex indices) of the nodes."""
    return Delaunay(nodes).simplices.astype(np.int64)


def cells(nodes, triangles, plane=None):
    """Background cells (M x 3 x 2 vertex coordinates) that tile the nodes'
    box: their Delaunay `triangles` (`triangulate`) or, where no node but its
    two ends lies on a mirror (the axis r = 0, or a `plane` z = plane of nodes
    in z >= plane: adapted nodes leave both, `cvt.lloyd`), the triangles of
    the nodes and of the feet on the mirror of the nodes whose Voronoi cells
    meet it, so that no sliver from end to end spans it. The nodes' mirror
    images would do it too, but a node pair and its images are always
    cocircular: which diagonal Qhull takes would then change the quadrature
    with the last bits of the nodes. Not collective."""
    feet = _feet(nodes, 0, 0.0)
    if plane is not None:
        feet = np.vstack([feet, _feet(nodes, 1, plane)])
    if len(feet) == 0:
        return nodes[triangles]
    nodes = np.vstack([nodes, feet])
    return nodes[triangulate(nodes)]


def _feet(nodes, normal, at, tol=1e-12):
    """The feet on the line x_normal = at, if no node but its two ends lies on
    it, of the nodes nearest to some point of it: with s the coordinate along
    the line and d the distance to it, |(s) - a|^2 = s^2 - 2 s s_a + (s_a^2 +
    d_a^2), so these are the vertices of the lower convex hull of (s_a, s_a^2
    + d_a^2)."""
    s, d = nodes[:, 1 - normal], nodes[:, normal] - at
    off = d > tol * max(1.0, abs(at))
    if (~off).sum() > 2:
        return nodes[:0]
    hull = ConvexHull(np.column_stack([s, s ** 2 + d ** 2]))
    lower = np.unique(hull.simplices[hull.equations[:, 1] < 0])
    lower = lower[off[lower]]
    feet = np.empty((len(lower), 2))
    feet[:, 1 - normal], feet[:, normal] = s[lower], at
    return feet


def _areas(v):
    """Unsigned areas of triangles (M x 3 x 2)."""
    return 0.5 * np.abs((v[:, 1, 0] - v[:, 0, 0]) * (v[:, 2, 1] - v[:, 0, 1])
                        - (v[:, 2, 0] - v[:, 0, 0]) * (v[:, 1, 1] - v[:, 0, 1]))


def rule(v, degree=4, axisymmetric=True):
    """Quadrature points (P x 2) and weights (P,) on the triangles `v`
    (M x 3 x 2 vertex coordinates, e.g. `cells`).

    Not collective. Exact for polynomials of `degree` in (r, z) in the planar
    measure; with `axisymmetric` the weights include 2 pi r (exact to degree-1).
    """
    if degree not in _RULES:
        raise ValueError(f"quadrature degree {degree} not in {DEGREES}")
    bary, wref = (np.asarray(a, dtype=float) for a in _RULES[degree])
    area = _areas(v)
    points = np.einsum('qk,mkd->mqd', bary, v).reshape(-1, 2)
    weights = (area[:, None] * wref[None, :]).ravel()
    if axisymmetric:
        weights = weights * 2.0 * np.pi * points[:, 0]
    return points, weights
