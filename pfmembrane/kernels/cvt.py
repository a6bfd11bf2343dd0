"""Centroidal Voronoi tessellation (CVT) relocation of meshfree nodes.

Nodes in the (r, z) box ``[0, Rb] x [0, Zb]`` are moved to a CVT for a
density ``rho >= 1`` (Du, Faber & Gunzburger, SIAM Rev. 41, 1999): every
node sits at the ``rho``-weighted centroid of its Voronoi cell.  In 2D the
node density of a CVT is asymptotically proportional to ``rho**(1/2)``, so
the spacing scales like ``rho**(-1/4)``.

Method.  Lloyd's iteration (move each node to its cell centroid) only
trades area between neighbouring cells: gathering a large share of the
nodes into a thin band takes it hundreds of steps.  `lloyd` therefore
first moves all nodes at once towards the density ``rho**(1/2)`` by a
deformation map (`_redistribute`), then polishes with over-relaxed Lloyd
steps.  On the 1000x band below with ~6,000 nodes, the CVT energy after the
map and ten Lloyd steps is lower than after 1,500 plain Lloyd steps.

Cell integrals.  Every Delaunay triangle ``(a, b, c)`` with circumcentre
``o`` is split into six signed triangles ``(a, m_ab, o)``, ``(a, o, m_ca)``,
... (``m`` are edge midpoints).  The pieces owned by a node sum, as signed
indicator functions, exactly to its Voronoi cell, obtuse triangles included
(their ``o`` lies outside and some pieces have negative area).  Clipping
the pieces to the box gives the box-clipped cells, and ``rho`` is only
evaluated in the box.  Each piece is integrated with the three-point
edge-midpoint rule, exact for the first moment of a linear ``rho``.  On the
CVTs of the 1000x band below, against the same pieces split 36-fold, the
centroid error of this rule is at most 1e-2 (RMS 6e-4) of the local
spacing; one point per piece, with a third of the density evaluations,
errs by up to 4e-2 (RMS 9e-3), as much as the distance to the centroids
at which the iteration stops.  Assigning samples to their nearest node
(cKDTree) instead still erred by 3e-3 of the spacing with 24,000 samples
per cell (random nodes, linear ``rho``).  The Delaunay triangulation,
needed either way, takes about 3/4 of the time of a step.

Edges.  Nodes on a box edge stay on it and move along it to the projection
of their clipped-cell centroid.  This is the constrained CVT (Du,
Gunzburger & Ju, 2003): the stationary point of the same energy with the
node confined to the edge, so edge nodes follow the ``rho**(1/2)`` grading
of their interior neighbours, where a separate 1D CVT of ``rho`` along the
edge would grade them like ``rho**(1/3)``.  Each edge keeps its node
count; the four corners are fixed.  A mirror edge (the plane of a half
box, the axis of a basis even in r) is not an edge of the solid: its
nodes are interior ones.

Measurements quoted in this module use the box ``[0, 2] x [0, 4]``, the
half circle ``d = |x - (0, 2)| - 1 = 0`` and ``rho = 1 + f (1 - phi**2)``
with ``phi = tanh(d / (sqrt(2) eps))``, ``eps = 0.0125`` (a band of width
~0.05) and ``f = 10, 100, 1000``, plus the unscaled
``rho = 1 + 1000 |grad phi|`` that peaks at 5.7e4; grids of 6,124 and
24,597 nodes start from a jittered lattice.
"""

import numpy as np
from scipy.fft import dctn, idctn
from scipy.ndimage import map_coordinates
from scipy.spatial import Delaunay, cKDTree

# Redistribution: grid vertices per node and flow time steps.  2 vertices
# per node gave a lower energy after the map than 1, 4 or 8.  Against 128
# steps, 16 steps leave the energy after the map 26% higher for the
# unscaled density (8% after ten Lloyd steps), 32 steps 5% (0.8%); for
# f <= 1000 both are within 1.2% (~6,000 nodes).
_GRID_VERTICES_PER_NODE = 2
_FLOW_STEPS = 32

# Over-relaxation of the Lloyd step.  A mode that Lloyd's map contracts by
# lambda is contracted by 1 - omega (1 - lambda): slow, smooth modes go
# faster, while the fastest ones still contract by |1 - omega| = 0.8.  On
# the 1000x band (6,124 nodes) this reaches the energy of n plain Lloyd
# steps in about 0.55 n steps; the energy fell at every step.
_OMEGA = 1.8


def _cross(u, v):
    """Scalar cross product of 2D vectors ``u, v`` (..., 2)."""
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _clip_halfplane(tri, owner, axis, bound, sign):
    """Clip triangles to the half-plane ``sign * (x[axis] - bound) >= 0``.

    A triangle with one vertex outside becomes two triangles, with two
    outside one, with three outside none.  Orientation is preserved, so
    signed areas keep their meaning.

    Parameters
    ----------
    tri : ndarray, shape (3, K, 2)
        Vertex-major triangles.
    owner : ndarray, shape (K,)
        Node index each triangle contributes to.
    axis : int
    bound : float
    sign : {1, -1}

    Returns
    -------
    tri : ndarray, shape (3, K', 2)
    owner : ndarray, shape (K',)
    """
    g = sign * (tri[:, :, axis] - bound)
    out = g < 0
    n_out = out.sum(axis=0)

    def rolled(sel, first):
        # A cyclic roll keeps the orientation; vertex ``first`` goes first.
        idx = (first + np.arange(3)[:, None]) % 3
        t = np.take_along_axis(tri[:, sel], idx[:, :, None], axis=0)
        gt = np.take_along_axis(g[:, sel], idx, axis=0)
        # Points where the edges 0-1 and 0-2 cross the line g = 0, put on
        # it exactly so that rho is never called just outside the box.
        cut = [t[0] + (t[k] - t[0]) * (gt[0] / (gt[0] - gt[k]))[:, None]
               for k in (1, 2)]
        for q in cut:
            q[:, axis] = bound
        return t, cut

    one = n_out == 1
    t, (q1, q2) = rolled(one, np.argmax(out[:, one], axis=0))
    quad = np.stack([np.concatenate([q1, q1]),
                     np.concatenate([t[1], t[2]]),
                     np.concatenate([t[2], q2])])
    two = n_out == 2
    t, (q1, q2) = rolled(two, np.argmin(out[:, two], axis=0))
    keep = n_out == 0
    return (np.concatenate([tri[:, keep], quad, np.stack([t[0], q1, q2])],
                           axis=1),
            np.concatenate([owner[keep], owner[one], owner[one],
                            owner[two]]))


def _cells(nodes, box, density):
    """Density-weighted centroids of the box-clipped Voronoi cells.

    Parameters
    ----------
    nodes : ndarray, shape (N, 2)
    box : tuple of float
        ``(Rb, Zb)``.
    density : callable
        ``density(points (M, 2)) -> (M,)``.

    Returns
    -------
    centroid : ndarray, shape (N, 2)
        ``int_V rho x / int_V rho``; a node without a cell keeps its place.
    area : ndarray, shape (N,)
        Geometric cell area.
    energy : float
        CVT energy ``sum_i int_{V_i} rho |x - z_i|^2``.
    """
    n = len(nodes)
    simp = Delaunay(nodes).simplices.T            # (3, T)
    det = _cross(nodes[simp[1]] - nodes[simp[0]],
                 nodes[simp[2]] - nodes[simp[0]])
    # Qhull does not orient its simplices: make them counter-clockwise.
    # Flat ones (no area in exact arithmetic) have no circumcentre.
    simp[1:, det < 0] = simp[:0:-1, det < 0]
    simp = simp[:, np.abs(det) > 1e-14 * np.abs(det).max()]
    v = nodes[simp]                               # (3, T, 2)
    b = v[1] - v[0]
    c = v[2] - v[0]
    bb = (b * b).sum(axis=1)
    cc = (c * c).sum(axis=1)
    o = v[0] + (np.stack([c[:, 1] * bb - b[:, 1] * cc,
                          b[:, 0] * cc - c[:, 0] * bb], axis=1)
                / (2.0 * _cross(b, c))[:, None])

    mid = 0.5 * (v + v[[1, 2, 0]])                # mid[k] on edge k, k+1
    o3 = np.broadcast_to(o, v.shape)
    tri = np.stack([np.concatenate([v, v]), np.concatenate([mid, o3]),
                    np.concatenate([o3, mid[[2, 0, 1]]])]).reshape(3, -1, 2)
    owner = np.concatenate([simp, simp]).ravel()

    # Only pieces with a circumcentre outside the box need clipping.
    rb, zb = box
    out = np.tile((o < 0).any(axis=1) | (o[:, 0] > rb) | (o[:, 1] > zb), 6)
    clipped, own = tri[:, out], owner[out]
    for axis, bound, sign in ((0, 0.0, 1), (0, rb, -1), (1, 0.0, 1),
                              (1, zb, -1)):
        clipped, own = _clip_halfplane(clipped, own, axis, bound, sign)
    tri = np.concatenate([tri[:, ~out], clipped], axis=1)
    owner = np.concatenate([owner[~out], own])

    area = 0.5 * _cross(tri[1] - tri[0], tri[2] - tri[0])
    qp = 0.5 * (tri + tri[[1, 2, 0]])             # edge-midpoint rule
    w = density(qp.reshape(-1, 2)).reshape(3, -1) * (area / 3.0)
    mass = np.bincount(owner, w.sum(axis=0), minlength=n)
    moment = np.stack([np.bincount(owner, (w * qp[:, :, k]).sum(axis=0),
                                   minlength=n) for k in range(2)], axis=1)
    centroid = np.divide(moment, mass[:, None], out=nodes.copy(),
                         where=mass[:, None] > 0)
    # Expanding |x - z|^2 loses about 6 of 16 digits: ample to compare.
    energy = ((w * (qp ** 2).sum(axis=2)).sum()
              - (nodes * (2.0 * moment - mass[:, None] * nodes)).sum())
    return centroid, np.bincount(owner, area, minlength=n), float(energy)


def _redistribute(nodes, box, density, area):
    """Globally move nodes so that their density approaches ``rho**(1/2)``.

    Deformation method (Liao & Anderson, Appl. Anal. 44, 1992): with the
    current node density ``f`` (one node per Voronoi cell) and the target
    ``g ~ rho**(1/2)``, both normalised to unit integral over the box,
    solve ``lap psi = f - g`` with Neumann conditions and follow
    ``dx/dt = grad psi / ((1 - t) f + t g)`` from ``t = 0`` to 1, which
    carries the density ``f`` onto ``g``.  The zero normal flux keeps edge
    nodes on their edges and corners in place.

    Parameters
    ----------
    nodes : ndarray, shape (N, 2)
    box : tuple of float
    density : callable
    area : ndarray, shape (N,)
        Voronoi cell areas of ``nodes``.

    Returns
    -------
    ndarray, shape (N, 2)
        Moved nodes, in the box.
    """
    spacing = np.sqrt(box[0] * box[1]
                      / (_GRID_VERTICES_PER_NODE * len(nodes)))
    size = [int(np.ceil(side / spacing)) + 1 for side in box]
    step = np.divide(box, np.subtract(size, 1))
    points = np.stack(np.meshgrid(*[np.linspace(0.0, side, m)
                                    for side, m in zip(box, size)],
                                  indexing="ij"), axis=-1).reshape(-1, 2)

    current = 1.0 / area[cKDTree(nodes).query(points)[1]].reshape(size)
    target = np.sqrt(density(points)).reshape(size)
    trapezoid = np.outer(*[np.r_[0.5, np.ones(m - 2), 0.5] for m in size])
    current /= (trapezoid * current).sum()
    target /= (trapezoid * target).sum()

    # The 5-point Laplacian with Neumann conditions on the vertex grid is
    # diagonal in the DCT-I basis.  Dropping the constant mode also absorbs
    # what is left of the mismatch between the two totals.
    eig = [-(2.0 - 2.0 * np.cos(np.pi * np.arange(m) / (m - 1))) / h ** 2
           for m, h in zip(size, step)]
    eig = eig[0][:, None] + eig[1][None, :]
    eig[0, 0] = 1.0
    coef = dctn(current - target, type=1) / eig
    coef[0, 0] = 0.0
    flux = np.gradient(idctn(coef, type=1), *step)
    flux[0][[0, -1], :] = 0.0
    flux[1][:, [0, -1]] = 0.0

    def velocity(x, t):
        # Bilinear interpolation, in grid index coordinates.
        at = [map_coordinates(field, (x / step).T, order=1, mode="nearest")
              for field in (*flux, current, target)]
        return np.stack(at[:2], axis=1) / ((1.0 - t) * at[2]
                                           + t * at[3])[:, None]

    # Explicit midpoint rule.
    dt = 1.0 / _FLOW_STEPS
    x = nodes.copy()
    for k in range(_FLOW_STEPS):
        half = np.clip(x + 0.5 * dt * velocity(x, k * dt), 0.0, box)
        x = np.clip(x + dt * velocity(half, (k + 0.5) * dt), 0.0, box)
    return x


def lloyd(nodes, box, density, max_iter=200, tol=1e-4, boundary_tol=1e-12,
          mirror=False, axis=False):
    """Relocate nodes to a density-weighted CVT of the box.

    A global redistribution (`_redistribute`) is tried first and kept only
    if it lowers the CVT energy, so a node set already close to the CVT is
    left to the Lloyd steps alone.  Each Lloyd step moves the interior
    nodes towards the centroids of their box-clipped Voronoi cells and the
    edge nodes towards those centroids projected on their edge, over-
    relaxed by a factor 1.8 unless that would leave the box; corners stay.

    Parameters
    ----------
    nodes : ndarray, shape (N, 2)
        Distinct ``(r, z)`` nodes in the box, including its four corners.
    box : tuple of float
        ``(Rb, Zb)``.
    density : callable
        Vectorized ``density(points (M, 2)) -> (M,)``, ``>= 1`` on the box;
        only called with points in the box.
    max_iter : int, optional
        Cap on the number of Lloyd steps.
    tol : float, optional
        Stop once the relative movement (see Returns) is below ``tol``.
        The default means nodes are, RMS, within 1% of the local spacing
        of their centroids.
    boundary_tol : float, optional
        Input nodes within this distance of a box edge are edge nodes.
    mirror : bool, optional
        The edge ``z = 0`` is a mirror plane (a half-box solve), not a
        boundary: its nodes, corners excepted, are interior nodes and leave
        it.  The clipped cells of the half box are the Voronoi cells of the
        node set mirrored across the plane, so this is that set's CVT, which
        has no nodes on the plane.  Held on it, the plane's row keeps its
        count of the uniform start while the refined nodes above it thin
        out: on the discocyte's grid O12 it ended 0.007 apart under rows
        0.027 away, and an alternating pattern of its nodal values became a
        near-null direction of the stage-2 Hessian.
    axis : bool, optional
        The edge ``r = 0`` is a mirror too (the axis of a solid of
        revolution whose basis is even in r): its nodes, corners excepted,
        leave it.  Held on it, the axis keeps its count where the refined
        nodes around it thin out, with the same near-null direction.

    Returns
    -------
    nodes : ndarray, shape (N, 2)
        Relocated nodes; edge nodes lie exactly on their edge (but for a
        `mirror` or the `axis`), corners are unchanged.  The result depends only on the input, bit for bit.
    iterations : int
        Number of Lloyd steps taken.  Steps that would raise the CVT energy
        are not taken: the iteration goes on with plain Lloyd steps, and
        ends when one of those would.  With a smooth ``rho`` this was not
        seen; with a jump in ``rho`` quadrature noise ends the iteration
        once the relative movement is down to about ``1e-4 .. 1e-3``.
    movement : float
        Relative movement of the last step, ``mean_i |c_i - z_i|^2 / A_i``
        with ``z_i`` the node before the step, ``c_i`` the (edge-projected)
        centroid of its cell and ``A_i`` the cell area: the mean squared
        plain Lloyd step in units of the local spacing.  ``inf`` if no step
        was taken.

    Raises
    ------
    ValueError
        If a node lies outside the box, a corner node is missing or two
        nodes coincide.
    """
    rb, zb = box
    z = np.array(nodes, dtype=float)
    on = np.stack([np.abs(z[:, 0]) <= boundary_tol,
                   np.abs(z[:, 0] - rb) <= boundary_tol,
                   np.abs(z[:, 1]) <= boundary_tol,
                   np.abs(z[:, 1] - zb) <= boundary_tol])
    inside = ((z >= -boundary_tol) & (z <= np.add(box, boundary_tol))).all()
    # The clipped cells tile the box only if its corners are nodes.
    corners = all((on[i] & on[j]).any() for i in (0, 1) for j in (2, 3))
    if not (inside and corners):
        raise ValueError("nodes must lie in the box and include its corners")
    z[on[0], 0], z[on[1], 0], z[on[2], 1], z[on[3], 1] = 0.0, rb, 0.0, zb
    plane = on[2] & (on[0] | on[1]) if mirror else on[2]
    held_axis = on[0] & (on[2] | on[3]) if axis else on[0]
    fixed = np.stack([held_axis | on[1], plane | on[3]], axis=1)

    centroid, area, energy = _cells(z, box, density)
    if (area <= 0).any():
        raise ValueError("nodes must be distinct")
    moved = np.where(fixed, z, _redistribute(z, box, density, area))
    cells = _cells(moved, box, density)
    if cells[2] < energy:
        z, (centroid, area, energy) = moved, cells

    omega = _OMEGA
    movement = np.inf
    it = 0
    while it < max_iter and movement >= tol:
        target = np.clip(np.where(fixed, z, centroid), 0.0, box)
        new = z + omega * (target - z)
        leaves = ((new < 0.0) | (new > box)).any(axis=1)
        new[leaves] = target[leaves]
        cells = _cells(new, box, density)
        # A plain Lloyd step cannot raise the energy, an over-relaxed one
        # can (not seen with a smooth rho): fall back to plain steps.  A
        # plain step that raises it is down to quadrature noise, e.g. for
        # a rho with a jump.
        if cells[2] > energy:
            if omega == 1.0:
                break
            omega = 1.0
            continue
        movement = float(np.mean(((target - z) ** 2).sum(axis=1) / area))
        z, (centroid, area, energy) = new, cells
        it += 1
    return z, it, movement
