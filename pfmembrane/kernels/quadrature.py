"""Background quadrature: Gauss rules on the Delaunay triangles of the nodes.

Weights carry the axisymmetric measure, so sum(w * f) = int_Omega f dOmega =
2 pi int int f r dr dz over the solid of revolution.
"""
import numpy as np
from scipy.spatial import Delaunay

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


def rule(nodes, triangles, degree=4, axisymmetric=True):
    """Quadrature points (P x 2) and weights (P,) on the given triangles.

    Not collective. Exact for polynomials of `degree` in (r, z) in the planar
    measure; with `axisymmetric` the weights include 2 pi r (exact to degree-1).
    """
    if degree not in _RULES:
        raise ValueError(f"quadrature degree {degree} not in {DEGREES}")
    bary, wref = (np.asarray(a, dtype=float) for a in _RULES[degree])
    v = nodes[triangles]                                  # M x 3 x 2
    area = 0.5 * np.abs((v[:, 1, 0] - v[:, 0, 0]) * (v[:, 2, 1] - v[:, 0, 1])
                        - (v[:, 2, 0] - v[:, 0, 0]) * (v[:, 1, 1] - v[:, 0, 1]))
    points = np.einsum('qk,mkd->mqd', bary, v).reshape(-1, 2)
    weights = (area[:, None] * wref[None, :]).ravel()
    if axisymmetric:
        weights = weights * 2.0 * np.pi * points[:, 0]
    return points, weights
