"""The zero level set of a field sampled on a raster, with numpy alone.

Marching squares as matplotlib's default contour algorithm (contourpy's
``mpl2014``) does it, so that `zero_contour` gives the polylines of
``contour(x, y, F, levels=[0.0]).allsegs[0]``: the same points (by the same
arithmetic, but for rounding in the first point of an open polyline), the
same orientation, first points and order, and repeated points merged.
"""

import numpy as np

__all__ = ["zero_contour"]


def zero_contour(x, y, F):
    """Polylines of F = 0 on the raster `x` by `y`.

    Raster points with F > 0 are inside, those with F <= 0 outside (as in
    matplotlib); each cell edge joining an inside to an outside point holds
    one point of the level set, linearly interpolated.  A cell with two
    inside corners on one diagonal and two outside on the other holds two
    segments: those cutting off the outside corners where the mean of the
    four corners is > 0, else those cutting off the inside ones.

    Parameters
    ----------
    x : array_like, shape (nx,)
    y : array_like, shape (ny,)
        Strictly increasing raster axes, nx, ny >= 2.
    F : array_like, shape (ny, nx)
        Finite values at the raster points: F[j, i] at (x[i], y[j]), as
        from ``np.meshgrid(x, y)``.

    Returns
    -------
    list of ndarray, shape (n, 2)
        The maximal polylines of (x, y) points, with F > 0 on their left:
        first the open ones, which start and end on the raster boundary,
        then the closed ones, which end with their first point.  Where a
        raster point holds F = 0 exactly, the level set passes through it,
        reached along each of its edges to an inside point: the repeated
        points are merged, and polylines left with fewer than 2 points
        (around an isolated zero minimum) dropped.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    F = np.asarray(F, dtype=float)
    if x.ndim != 1 or y.ndim != 1 or F.shape != (y.size, x.size) or min(F.shape) < 2:
        raise ValueError(f"F must have shape (len(y), len(x)) with both >= 2, "
                         f"got {F.shape} for {y.shape} and {x.shape}")
    ny, nx = F.shape
    # Edge ids: the horizontal edge from (j, i) to (j, i + 1) is j (nx - 1) + i,
    # the vertical one from (j, i) to (j + 1, i) is n_h + j nx + i.
    n_h = ny * (nx - 1)
    inside = F > 0.0
    # Only the cells with corners on both sides hold segments; the rest of
    # the work is on those.
    sw, se, ne, nw = inside[:-1, :-1], inside[:-1, 1:], inside[1:, 1:], inside[1:, :-1]
    cells = np.flatnonzero((sw | se | ne | nw) & ~(sw & se & ne & nw))
    j, i = np.divmod(cells, nx - 1)
    # Cell sides counterclockwise, S E N W: side k runs from corner k to
    # corner k + 1 of SW SE NE NW.
    sides = [cells, n_h + cells + j + 1, cells + nx - 1, n_h + cells + j]
    corners = [inside[j, i], inside[j, i + 1], inside[j + 1, i + 1], inside[j + 1, i]]
    # With F > 0 on its left, the level set enters a cell across the sides
    # that run from an inside to an outside corner and leaves across the others.
    enters = [corners[k] & ~corners[(k + 1) % 4] for k in range(4)]
    leaves = [~corners[k] & corners[(k + 1) % 4] for k in range(4)]
    # It turns clockwise (not to the next side counterclockwise) in a saddle
    # cell whose mean is <= 0 (summed as matplotlib does, for the same sign
    # where it is tiny): the segments then cut off the inside corners.
    clockwise = ((corners[0] == corners[2]) & (corners[1] == corners[3])
                 & (0.25 * (F[j, i] + F[j, i + 1] + F[j + 1, i] + F[j + 1, i + 1]) <= 0.0))

    source, target, order = [], [], []
    for k, rank in zip(range(4), (0, 3, 2, 1)):
        entering = enters[k]
        left = leaves[(k + 1) % 4][entering] & ~clockwise[entering]
        right = leaves[(k + 3) % 4][entering]
        source.append(sides[k][entering])
        target.append(np.where(left, sides[(k + 1) % 4][entering],
                               np.where(right, sides[(k + 3) % 4][entering],
                                        sides[(k + 2) % 4][entering])))
        # matplotlib starts open polylines cell by cell, on S, W, N, E.
        order.append(4 * cells[entering] + rank)
    source, target, order = (np.concatenate(a) for a in (source, target, order))

    # Across an interior edge the level set leaves one cell into the next, so
    # each edge starts at most one segment and ends at most one: the segments
    # chain into paths from boundary to boundary, and cycles.
    entered = np.zeros(n_h + (ny - 1) * nx, dtype=bool)
    entered[target] = True
    boundary = ~entered[source]
    starts = source[boundary][np.argsort(order[boundary])].tolist()
    following = dict(zip(source.tolist(), target.tolist()))
    lines = []
    for edge in starts:
        line = [edge]
        while edge in following:
            edge = following.pop(edge)
            line.append(edge)
        lines.append(line)
    # What is left are cycles, each crossing vertical edges; matplotlib starts
    # each at its first, the leftmost on the lowest raster row it meets, and
    # orders them so.
    for first in sorted(e for e in following if e >= n_h):
        if first not in following:
            continue                                # on a cycle already traced
        line, edge = [first], first
        while True:
            edge = following.pop(edge)
            line.append(edge)
            if edge == first:
                break
        lines.append(line)
    if not lines:
        return []

    edges = np.concatenate(lines)
    vertical = edges >= n_h
    j0, i0 = np.where(vertical, np.divmod(edges - n_h, nx), np.divmod(edges, nx - 1))
    j1, i1 = j0 + vertical, i0 + ~vertical
    # Interpolate from the outside end b to the inside end a as matplotlib does:
    # fraction = F_a / (F_a - F_b) > 0, so that F_b = 0 gives the point b exactly.
    swap = inside[j0, i0]
    jb, ib = np.where(swap, j1, j0), np.where(swap, i1, i0)
    ja, ia = np.where(swap, j0, j1), np.where(swap, i0, i1)
    fraction = F[ja, ia] / (F[ja, ia] - F[jb, ib])
    points = np.column_stack([x[ib] * fraction + x[ia] * (1.0 - fraction),
                              y[jb] * fraction + y[ja] * (1.0 - fraction)])

    begins = np.cumsum([0] + [len(line) for line in lines[:-1]])
    keep = np.ones(len(points), dtype=bool)
    keep[1:] = np.any(points[1:] != points[:-1], axis=1)
    keep[begins] = True
    pieces = np.split(points[keep], np.cumsum(keep)[begins[1:] - 1])
    return [piece for piece in pieces if len(piece) > 1]
