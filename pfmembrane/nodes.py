"""Node sets of the (r, z) box: uniform grids, boundary classes, axis mirrors.

Pure numpy/scipy; every rank builds the same node set deterministically.
"""
import numpy as np

# Edge labels; the axis r = 0 is a symmetry line, the other three carry phi = -1.
AXIS, OUTER, BOTTOM, TOP = 1, 2, 4, 8


def _hex_grid(box, h):
    """Edge nodes at spacing ~h plus a staggered (hexagonal) lattice whose even
    rows start on the axis: mirrored across r = 0 it stays a regular lattice, so
    the axis adds no irregularity to the basis (nor error to phi_r / r)."""
    Rb, Zb = box
    nr = max(int(round(Rb / h)), 2)
    r_edge = np.linspace(0.0, Rb, nr + 1)
    rows = max(int(round(Zb / (h * np.sqrt(3.0) / 2.0))), 2)
    dz = Zb / rows
    z_rows = dz * np.arange(1, rows)
    parts = [np.column_stack([r_edge, np.zeros_like(r_edge)]),
             np.column_stack([r_edge, np.full_like(r_edge, Zb)]),
             np.column_stack([np.full(rows - 1, Rb), z_rows])]
    for j, z in enumerate(z_rows, start=1):
        r = np.arange(0.5 * h * (j % 2), Rb - 0.5 * h, h)
        parts.append(np.column_stack([r, np.full_like(r, z)]))
    return np.vstack(parts)


def uniform(box, n):
    """Near-uniform node set of about `n` nodes with nodes on all four edges.

    Not collective. The lattice spacing is found by bisection on the actual
    count, so the result is deterministic and within a few nodes of `n`.
    """
    Rb, Zb = box
    lo, hi = 1e-4 * min(Rb, Zb), 0.5 * min(Rb, Zb)
    for _ in range(60):
        h = np.sqrt(lo * hi)
        if len(_hex_grid(box, h)) > n:
            lo = h
        else:
            hi = h
    return _hex_grid(box, hi if abs(len(_hex_grid(box, hi)) - n) <= abs(len(_hex_grid(box, lo)) - n) else lo)


def edge_labels(nodes, box, tol=1e-12):
    """Bit mask of the box edges each node lies on (AXIS, OUTER, BOTTOM, TOP)."""
    Rb, Zb = box
    r, z = nodes[:, 0], nodes[:, 1]
    scale = tol * max(Rb, Zb)
    return (AXIS * (r <= scale) + OUTER * (r >= Rb - scale)
            + BOTTOM * (z <= scale) + TOP * (z >= Zb - scale)).astype(np.int8)


def dirichlet_mask(nodes, box):
    """Nodes on r = Rb, z = 0 or z = Zb: their value is fixed to phi = -1."""
    return (edge_labels(nodes, box) & (OUTER | BOTTOM | TOP)) != 0


def with_axis_mirrors(nodes, beta, radius):
    """Append the reflections r -> -r of the nodes within `radius` of the axis.

    A mirror carries its original's beta and, when the caller adds each
    mirror's basis column to its original's, the approximation space is exactly
    even in r: phi_r(0, z) = 0 for every nodal vector and phi_r / r stays
    bounded (it tends to phi_rr), without extra unknowns. Nodes on the axis are
    their own mirrors and are not duplicated. Returns the augmented nodes, betas
    and, for every augmented node, the index of the original it belongs to.
    """
    near = np.flatnonzero((nodes[:, 0] > 0.0) & (nodes[:, 0] < radius))
    mirrors = nodes[near] * np.array([-1.0, 1.0])
    owner = np.concatenate([np.arange(len(nodes)), near])
    return np.vstack([nodes, mirrors]), np.concatenate([beta, beta[near]]), owner


def nodal_spacing(nodes, axis=True):
    """h_a: mean distance from each node to its Delaunay (Voronoi) neighbours.

    With `axis`, the neighbours are found with the nodes reflected across r = 0,
    as the basis sees them: otherwise nodes on the axis, missing half their
    neighbours, get a different beta_a from their neighbours and the basis
    (and phi_rr) loses accuracy next to the axis.
    """
    from scipy.spatial import Delaunay
    if axis:
        off = nodes[:, 0] > 0.0
        full = np.vstack([nodes, nodes[off] * np.array([-1.0, 1.0])])
        return nodal_spacing(full, axis=False)[:len(nodes)]
    tri = Delaunay(nodes).simplices
    edges = np.unique(np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]]), 1), axis=0)
    length = np.linalg.norm(nodes[edges[:, 0]] - nodes[edges[:, 1]], axis=1)
    n = len(nodes)
    total = np.bincount(edges[:, 0], length, n) + np.bincount(edges[:, 1], length, n)
    return total / (np.bincount(edges[:, 0], minlength=n) + np.bincount(edges[:, 1], minlength=n))


def spacing_peak(h, bins=60, significance=0.1):
    """h_min: the left peak of the distribution of h (Appendix B).

    The histogram (lightly smoothed) is searched for local maxima holding at
    least `significance` of the highest bin; the smallest-h one is returned.
    A uniform grid has a single peak; an adapted grid's refined band forms the
    left one.
    """
    counts, edges = np.histogram(h, bins=bins)
    smooth = np.convolve(counts, [0.25, 0.5, 0.25], mode='same')
    padded = np.concatenate([[-1.0], smooth, [-1.0]])
    peaks = np.flatnonzero((smooth >= padded[:-2]) & (smooth >= padded[2:])
                           & (smooth >= significance * smooth.max()))
    i = peaks[0]
    return 0.5 * (edges[i] + edges[i + 1])
