"""Nodes graded about a curve: spacing h0 within `width` of the membrane's (r, z)
curve, growing by `grading` per unit distance beyond it up to `h_max`, placed as
the CVT of the density that spacing asks for.

A uniform grid that resolves eps everywhere pays for the bulk, where phi is
+-1, at the interface's spacing: its node count grows like 1 / eps^2, the
graded one's like 1 / eps (the membrane's length over the spacing, times the
band's width over the spacing). The spacing is a function of the distance d
to the curve alone,

    h(d) = min(h_max, h0 + grading max(d - width, 0)),

flat across the interface (max-ent's Laplacian errs where the spacing changes,
which the flat band keeps out of it) and growing linearly outside. A CVT's
node density goes like rho^(1/2) (`cvt`), so rho = (h_max / h)^4 >= 1, placed by the CVT of
node adaptivity (`adapt.cvt_nodes`).

Pure numpy/scipy; every rank builds the same node set deterministically.
"""
import math

import numpy as np
from scipy.spatial import cKDTree

from pfmembrane.kernels.adapt import cvt_nodes
from pfmembrane.kernels.nodes import raster_axes, uniform

HEX = math.sqrt(3.0) / 2.0  # area per node of a hexagonal lattice of spacing h, over h^2
RASTER = 0.5                # raster step / h0
CURVE_STEP = 0.25           # the curve resampled at this fraction of h0 for its distance


def spacing(distance, h0, width, grading, h_max):
    """h(d) of the module docstring."""
    return np.minimum(h_max, h0 + grading * np.maximum(distance - width, 0.0))


def curve_distance(points, curves, step):
    """The distance from `points` (M, 2) to the polylines `curves` (each (K, 2)
    in (r, z)) and to their mirror images across the axis, resampled at `step`."""
    dense = []
    for c in curves:
        c = np.asarray(c, dtype=float)
        seg = np.linalg.norm(np.diff(c, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        t = np.linspace(0.0, s[-1], max(int(math.ceil(s[-1] / step)) + 1, 2))
        dense.append(np.column_stack([np.interp(t, s, c[:, 0]), np.interp(t, s, c[:, 1])]))
    dense = np.vstack(dense)
    dense = np.vstack([dense, dense * [-1.0, 1.0]])
    return cKDTree(dense).query(points)[0]


def spacing_raster(curves, box, h0, width, grading, h_max, plane=None):
    """(r, z, h): the raster axes of the box (of its half z >= plane with a mirror plane)
    at RASTER h0 and h(d) of the module docstring on it (rows z, columns r)."""
    r, z = raster_axes(box, RASTER * h0, plane or 0.0)
    R, Z = np.meshgrid(r, z, indexing='xy')
    d = curve_distance(np.column_stack([R.ravel(), Z.ravel()]), curves, CURVE_STEP * h0)
    return r, z, spacing(d, h0, width, grading, h_max).reshape(len(z), len(r))


def node_count(r, z, h):
    """The nodes a hexagonal lattice of the local spacing h puts on the raster (r, z)."""
    return int(math.ceil(np.sum(1.0 / (HEX * h * h)) * (r[1] - r[0]) * (z[1] - z[0])))


def graded_nodes(r, z, h, box, plane=None):
    """(nodes, Lloyd steps, movement): `node_count` nodes of the box (of its half z >=
    plane) with the spacing h of the raster (r, z), corners and edge nodes included: the
    CVT of rho = (max h / h)^4 (`adapt.cvt_nodes`) from a uniform grid of that count."""
    start = uniform(box, node_count(r, z, h) * (2 if plane is not None else 1),
                    half=plane is not None)
    return cvt_nodes(start, box, (h.max() / h) ** 4 - 1.0, r, z, 1.0, plane)
