"""Node sets of the (r, z) box: uniform grids, boundary classes, mirrors.

Two mirrors make folded bases: the axis r = 0 always, and for up-down
symmetric scenes solved on the half box z >= Zb / 2 the plane z = Zb / 2.

Pure numpy/scipy; every rank builds the same node set deterministically.
"""
import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import Delaunay

# Edge labels; the axis r = 0 is a symmetry line, the other three carry phi = -1.
AXIS, OUTER, BOTTOM, TOP = 1, 2, 4, 8


def _hex_grid(box, h, symmetric=False):
    """Edge nodes at spacing ~h plus a staggered (hexagonal) lattice whose even
    rows start on the axis: mirrored across r = 0 it stays a regular lattice, so
    the axis adds no irregularity to the basis (nor error to phi_r / r).
    `symmetric` rounds the row count to a multiple of 4: an even row, with
    its node on the axis, then lies on z = Zb / 2 and the lattice is its own
    mirror image across that plane (the 6124-node lattice already is)."""
    Rb, Zb = box
    nr = max(int(round(Rb / h)), 2)
    r_edge = np.linspace(0.0, Rb, nr + 1)
    rows = Zb / (h * np.sqrt(3.0) / 2.0)
    rows = max(4 * int(round(rows / 4)) if symmetric else int(round(rows)), 2)
    dz = Zb / rows
    z_rows = dz * np.arange(1, rows)
    parts = [np.column_stack([r_edge, np.zeros_like(r_edge)]),
             np.column_stack([r_edge, np.full_like(r_edge, Zb)]),
             np.column_stack([np.full(rows - 1, Rb), z_rows])]
    for j, z in enumerate(z_rows, start=1):
        r = np.arange(0.5 * h * (j % 2), Rb - 0.5 * h, h)
        parts.append(np.column_stack([r, np.full_like(r, z)]))
    return np.vstack(parts)


def uniform(box, n, half=False):
    """Near-uniform node set of about `n` nodes with nodes on all four edges.

    Not collective. The lattice spacing is found by bisection on the actual
    count, so the result is deterministic and within a few nodes of `n`.
    With `half`, the nodes with z >= Zb / 2 of the n-node lattice that is
    symmetric across z = Zb / 2 (about n / 2 nodes, a row on the plane).
    """
    Rb, Zb = box
    lo, hi = 1e-4 * min(Rb, Zb), 0.5 * min(Rb, Zb)
    count = lambda h: len(_hex_grid(box, h, symmetric=half))  # noqa: E731
    for _ in range(60):
        h = np.sqrt(lo * hi)
        if count(h) > n:
            lo = h
        else:
            hi = h
    nodes = _hex_grid(box, hi if abs(count(hi) - n) <= abs(count(lo) - n) else lo, symmetric=half)
    if half:
        nodes = nodes[nodes[:, 1] >= 0.5 * Zb * (1.0 - 1e-12)]
        # the row dz * rows / 2 can miss Zb / 2 by an ulp: on the plane exactly, else its
        # mirror image is a near-duplicate node and the spacing there is undefined
        nodes[np.abs(nodes[:, 1] - 0.5 * Zb) <= 1e-12 * Zb, 1] = 0.5 * Zb
    return nodes


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


def with_mirrors(nodes, beta, radius, plane=None):
    """Append the reflections r -> -r of the nodes within `radius` of the axis
    and, given a `plane`, the reflections z -> 2 plane - z of those and of the
    axis mirrors within `radius` of z = plane.

    A mirror carries its original's beta and, when the caller adds each
    mirror's basis column to its original's, the approximation space is exactly
    even in r: phi_r(0, z) = 0 for every nodal vector and phi_r / r stays
    bounded (it tends to phi_rr), without extra unknowns; likewise
    phi_z = 0 on the plane. Nodes on a mirror are their own images and are
    not duplicated. Returns the augmented nodes, betas and, for every
    augmented node, the index of the original it belongs to.
    """
    radius = np.broadcast_to(radius, beta.shape)
    owner = np.arange(len(nodes))
    near = np.flatnonzero((nodes[:, 0] > 0.0) & (nodes[:, 0] < radius))
    owner = np.concatenate([owner, near])
    aug = np.vstack([nodes, nodes[near] * np.array([-1.0, 1.0])])
    if plane is not None:
        above = aug[:, 1] - plane
        near = np.flatnonzero((above > 0.0) & (above < radius[owner]))
        owner = np.concatenate([owner, owner[near]])
        aug = np.vstack([aug, np.column_stack([aug[near, 0], 2.0 * plane - aug[near, 1]])])
    return aug, beta[owner], owner


def unfold(nodes, phi, plane):
    """The full-box node set and nodal values of a half-box solution: the
    nodes above `plane` reflected below it."""
    above = nodes[:, 1] > plane
    mirrored = np.column_stack([nodes[above, 0], 2.0 * plane - nodes[above, 1]])
    return np.vstack([nodes, mirrored]), np.concatenate([phi, phi[above]])


def nodal_spacing(nodes, axis=True, smoothing=0, plane=None):
    """h_a: mean distance from each node to its Delaunay (Voronoi) neighbours.

    With `axis`, the neighbours are found with the nodes reflected across r = 0
    (and across z = `plane` when given), as the basis sees them: otherwise
    nodes on a mirror, missing half their neighbours, get a different beta_a
    from their neighbours and the basis (and phi_rr) loses accuracy there.

    `smoothing` passes h_a <- (h_a + mean of the neighbours' h) / 2 remove the
    node-to-node scatter of h on irregular (CVT) node sets, which otherwise
    passes into beta_a and the basis: on a CVT of uniform density at 6,124
    nodes three passes bring the discocyte energy at eps = 0.04 from +0.14%
    to +0.03% of the hexagonal lattice's. On a lattice h is constant and the
    passes change nothing away from the box edges.
    """
    return nodal_spacings(nodes, smoothing, plane, axis)[1]


def nodal_spacings(nodes, smoothing, plane=None, axis=True):
    """The raw and the smoothed h_a of `nodal_spacing`, from one triangulation.

    A node set and its mirror images are symmetric: an edge from a node off
    a mirror to an image across it of another node crosses its own mirror
    image, so both are the diagonals of an empty cocircular quadrilateral and
    Qhull keeps one of them at random. Those edges are left out, else h_a near
    a mirror jumps with the last bits of the nodes (by up to 0.003, a fifth
    of h, on the discocyte's half-box grid O11). Kept are the edges to a
    node's own image across one mirror, and to any image across mirrors the
    node lies on.
    """
    n = len(nodes)
    full, owner = nodes, np.arange(n)
    if axis:
        full, _, owner = with_mirrors(nodes, np.zeros(n), np.inf, plane)
    indptr, neighbours = Delaunay(full).vertex_neighbor_vertices
    a = np.repeat(np.arange(len(full)), np.diff(indptr))
    across_axis = full[:, 0] < 0.0
    across_plane = full[:, 1] < plane if plane is not None else np.zeros(len(full), bool)
    b = neighbours
    keep = (a < n) & ((b < n)
                      | ((~across_axis[b] | (full[a, 0] == 0.0))
                         & (~across_plane[b] | (full[a, 1] == plane)))
                      | ((owner[b] == a) & (across_axis[b] != across_plane[b])))
    a, b = a[keep], b[keep]
    count = np.bincount(a, minlength=n)
    dist = np.linalg.norm(full[b] - full[a], axis=1)
    raw = h = np.bincount(a, dist, minlength=n) / count
    for _ in range(smoothing):
        h = 0.5 * h + 0.5 * np.bincount(a, h[owner[b]], minlength=n) / count
    return raw, h


def raster_axes(box, step, z0=0.0):
    """Axes (r, z) of the regular raster of [0, Rb] x [z0, Zb] with spacing at most `step`."""
    r = np.linspace(0.0, box[0], int(np.ceil(box[0] / step)) + 1)
    z = np.linspace(z0, box[1], int(np.ceil((box[1] - z0) / step)) + 1)
    return r, z


def spacing_peak(h, bins=128):
    """Smallest-spacing peak ``h_min`` of the distribution of ``h``.

    The histogram of ``log h`` is smoothed with a Gaussian of width 0.05,
    i.e. about 5% in spacing, and padded with empty bins so that a peak in
    an end bin counts.  Working in ``log h`` resolves a refined and a
    coarse population alike, as each is spread by a similar relative
    amount.  The width merges sub-peaks a few per cent apart, such as the
    nodes with 5 or 7 neighbours in a uniform CVT, which sit about 7% below
    and 5% above the 6-neighbour peak.  Local maxima with a prominence of
    at least 1% of the highest one are peaks.  On the CVTs of the band
    densities of tests/test_cvt.py the result is 2-4% above the median spacing
    of the nodes within 0.01 of the curve.  The weakest band there, 10x
    with 2.5% of the nodes, stands out by 1.0-1.5%; spurious maxima stayed
    below 0.6%.

    Parameters
    ----------
    h : array_like, shape (N,)
        Positive nodal spacings, e.g. from `nodal_spacing`.
    bins : int, optional
        Number of histogram bins between the smallest and largest ``h``.

    Returns
    -------
    float
        Centre of the bin of the leftmost peak: the spacing of a uniform
        grid, or that of the refined nodes of a grid refined around a band.
    """
    x = np.log(np.asarray(h, dtype=float))
    if np.ptp(x) < 1e-12:
        return float(np.exp(x[0]))
    counts, edges = np.histogram(x, bins=bins)
    smooth = np.r_[0.0, gaussian_filter1d(counts.astype(float),
                                          0.05 / (edges[1] - edges[0]),
                                          mode="constant"), 0.0]
    first = first_peak(smooth, 0.01 * smooth.max()) - 1
    return float(np.exp(0.5 * (edges[first] + edges[first + 1])))


def first_peak(y, prominence):
    """Index of the leftmost strict local maximum of ``y`` whose prominence
    (its height above the higher of the lowest values between it and the
    nearest higher value on either side, or the end) is at least
    `prominence`: ``scipy.signal.find_peaks(y, prominence=...)[0][0]`` for
    peaks one sample wide, without the 0.2 s import of scipy.signal that
    every run would pay."""
    y = np.asarray(y, dtype=float)
    for i in np.flatnonzero((y[1:-1] > y[:-2]) & (y[1:-1] > y[2:])) + 1:
        higher = np.flatnonzero(y > y[i])
        left, right = higher[higher < i], higher[higher > i]
        lo = y[left[-1] + 1 if left.size else 0:i].min()
        hi = y[i + 1:right[0] if right.size else y.size].min()
        if y[i] - max(lo, hi) >= prominence:
            return int(i)
    raise ValueError("no peak of that prominence")
