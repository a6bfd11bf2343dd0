"""The zero level set of a 3D phase field: triangulation, topology and Canham-Helfrich energy.

Pure numpy/scipy (no MPI, no PETSc): the 3D counterpart of `pfmembrane.analysis.levelset`,
which measures the axisymmetric level set phi_h(r, z) = 0 as meridian curves.

Conventions (those of `levelset` and `pfmembrane.sharp`):

- phi is about +1 inside the vesicle and -1 outside; the membrane is phi = 0 and its outward
  normal is n = -grad phi / |grad phi|, pointing out of the region phi > 0.
- E = (k/2) int (H - C0)^2 dS, H = (kappa1 + kappa2) / 2 the mean curvature for that normal:
  H = div(n) / 2 = +1/R on a sphere of radius R holding phi > 0, so E = 2 pi k (1 - C0 R)^2
  (2 pi k at C0 = 0; a torus of radii a > b: (k/2) pi^2 a^2 / (b sqrt(a^2 - b^2)) at C0 = 0,
  pi^2 k for the Clifford torus a = sqrt(2) b).
- C0 is the checkpoint's ``c0`` attribute itself, an inverse length in the units of the scene:
  `levelset.level_set_energy`, `loop_energy` and `_sphere_energy` pass ``attrs['c0']``
  unchanged as C0 of `pfmembrane.sharp.shape_energy` (whose integrand is H - c0), so the
  parameter ``c0`` here has exactly that meaning (no factor of the radius, no 2H - C0).
- A component with phi > 0 outside it (orientation -1: a hole of phi < 0 inside the vesicle,
  e.g. the inner sphere of a stomatocyte) has its outward normal of phi > 0 pointing into it:
  H = -1/b on such an inner sphere of radius b, E = 2 pi k (1 + C0 b)^2. This is
  `levelset.components_energy`'s rule (there: the surface with -phi, and C0 -> -C0). Here it
  needs no special case: H is computed from grad phi and its Hessian with n = -grad phi / |grad
  phi| everywhere, which is that normal on every component. The orientation is reported, and
  taken from the sign of phi as in levelset: the triangles are oriented from phi > 0 to
  phi < 0, so a component's signed enclosed volume is > 0 where phi > 0 lies inside it.

Method: phi is sampled on a Cartesian grid; every cube is split into the six tetrahedra along
its main diagonal (one per order of the three axes), the same in every cube, so that
neighbouring cubes share their face diagonals and the tetrahedra form one simplicial complex
of the box: marching tetrahedra then has no ambiguous case and gives a closed, consistently
oriented, manifold surface away from the box sides. A vertex is identified with the grid edge
it lies on, so that the tetrahedra sharing an edge share the vertex (the Euler characteristic
counts it once).
Nodes with phi = 0 count as outside (phi > 0 is inside), a consistent choice, so the
combinatorics hold whatever the values; geometric degeneracy is avoided rather than repaired:
each vertex is placed at the root of phi along its grid edge (bracketed regula falsi, which
converges also for a steep tanh profile where Newton from a linear interpolation diverges),
its edge parameter kept in [TMIN, 1 - TMIN] so that no two vertices coincide, then polished by
Newton steps along grad phi. No triangle is dropped: removing a zero-area one would open the
surface (its edges are shared), and one of tiny area adds nothing to the integrals.

The energy integrand (H - C0)^2 is evaluated at the vertices (H exact there up to the
vertex's |phi|, from the implicit-surface formula) and integrated as the vertex average times
the flat triangle's area; the errors are those of the inscribed triangulation, O(step^2).
"""

import itertools
from dataclasses import dataclass, field as _field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["Surface", "Component", "Energy", "Measurement", "extract", "components",
           "mean_curvature", "helfrich_energy", "measure"]

CHUNK = 200_000        # points per call of the field
TMIN = 1e-6            # edge parameters of the vertices lie in [TMIN, 1 - TMIN]
EDGE_ITERATIONS = 60   # regula falsi steps along a grid edge, at most
EDGE_TOL = 1e-12       # ... until the bracket is this fraction of the edge
NEWTON_STEPS = 3       # projection along grad phi after the edge root
PROJECT_TOL = 1e-13    # ... of the vertices where |phi| is above this: below it phi's own
                       # rounding, not the vertex's distance, sets it, and halved steps fail


@dataclass
class Surface:
    """A triangulated closed surface (where it does not leave the box).

    Attributes
    ----------
    vertices : ndarray, shape (nv, 3)
        On phi = 0 (up to the projection's last step).
    triangles : ndarray, shape (nt, 3)
        Vertex indices, counterclockwise seen from outside (phi < 0): the cross product
        (v1 - v0) x (v2 - v0) points along n = -grad phi.
    step : float
        The grid spacing the surface was extracted with.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    step: float = np.nan


@dataclass
class Component:
    """One connected piece of a `Surface` (triangles connected through shared edges).

    Attributes
    ----------
    triangles : ndarray
        Indices into the surface's triangles.
    area : float
    volume : float
        Signed enclosed volume (divergence theorem with the surface's orientation): > 0 where
        phi > 0 lies inside the component, < 0 for a hole of phi < 0.
    chi : int
        Euler characteristic V - E + F.
    genus : float
        (2 - chi) / 2 for a closed component; NaN for one that leaves the box.
    closed : bool
        Every edge is shared by exactly two triangles.
    orientation : int
        +1 where phi > 0 lies inside (a vesicle), -1 where it lies outside (a hole), as
        `levelset.Component.orientation`.
    parent : int or None
        The smallest closed component that encloses this one (winding number of one of its
        vertices), or None.
    """

    triangles: np.ndarray
    area: float
    volume: float
    chi: int
    genus: float
    closed: bool
    orientation: int
    parent: object = None

    @property
    def count(self):
        """Number of triangles."""
        return int(self.triangles.size)

    @property
    def nested(self):
        """Enclosed by another component."""
        return self.parent is not None


@dataclass
class Energy:
    """`helfrich_energy`: the total and that of each component (in `components` order)."""

    total: float
    per_component: list


@dataclass
class Measurement:
    """`measure`: energy, area and signed volume summed over the components, their count and
    total genus, and the components themselves (with their energies)."""

    energy: float
    area: float
    volume: float
    components: int
    genus: float
    per_component: list = _field(default_factory=list)
    surface: Surface = None


# The unit cube's six tetrahedra: one per permutation of the axes, the
# path 000 -> 000 + e_p0 -> ... -> 111. Any two of its vertices are ordered componentwise, so
# each of its edges runs from a corner u to u + o, o one of the 7 nonzero 0/1 offsets.
_OFFSETS = [o for o in itertools.product((0, 1), repeat=3) if any(o)]
_OFFSET_CODE = {o: i for i, o in enumerate(_OFFSETS)}


def _tetrahedra():
    tets = []
    for perm in itertools.permutations(range(3)):
        corner = np.zeros(3, dtype=int)
        path = [corner.copy()]
        for axis in perm:
            corner[axis] = 1
            path.append(corner.copy())
        tets.append(np.array(path))
    return tets


_TETS = _tetrahedra()
_PAIRS = list(itertools.combinations(range(4), 2))   # the 6 edges of a tetrahedron


def _case_table():
    """Triangles of each tetrahedron and sign pattern, as local edge numbers (0..5), -1 where
    there is none; ordered so that the normal points from the inside vertices (phi > 0, bit set
    in the pattern) to the outside ones. Decided on the unit cube with the vertices at the edge
    midpoints: the order depends only on which edges carry them (the orientation of such a
    triangle cannot flip as the vertices move along their edges)."""
    table = -np.ones((6, 16, 2, 3), dtype=int)
    for t, tet in enumerate(_TETS):
        for pattern in range(1, 15):
            inside = [(pattern >> i) & 1 for i in range(4)]
            cut = [e for e, (i, j) in enumerate(_PAIRS) if inside[i] != inside[j]]
            mid = {e: 0.5 * (tet[_PAIRS[e][0]] + tet[_PAIRS[e][1]]) for e in cut}
            if len(cut) == 3:
                polygons = [cut]
            else:   # a quadrilateral: order it round, split it along a diagonal
                a, b = [i for i in range(4) if inside[i]]
                c, d = [i for i in range(4) if not inside[i]]
                e = {frozenset(p): n for n, p in enumerate(_PAIRS)}
                ring = [e[frozenset((a, c))], e[frozenset((b, c))], e[frozenset((b, d))],
                        e[frozenset((a, d))]]
                polygons = [ring[:3], [ring[0], ring[2], ring[3]]]
            away = (np.mean([tet[i] for i in range(4) if not inside[i]], axis=0)
                    - np.mean([tet[i] for i in range(4) if inside[i]], axis=0))
            for s, tri in enumerate(polygons):
                p = [mid[e] for e in tri]
                if np.cross(p[1] - p[0], p[2] - p[0]) @ away < 0:
                    tri = [tri[0], tri[2], tri[1]]
                table[t, pattern, s] = tri
    return table


_TABLE = _case_table()


def _call(field, points, what=(0, 1, 2)):
    """The field at (n, 3) points in chunks of at most CHUNK: the parts `what` of
    (phi, grad, hess)."""
    parts = [[] for _ in what]
    for start in range(0, len(points), CHUNK):
        out = field(points[start:start + CHUNK])
        out[max(what)]  # the highest part first: a lazy field computes the lower with it
        for store, i in zip(parts, what):
            store.append(np.asarray(out[i], dtype=float))
    return [np.concatenate(p) if p else np.zeros((0,)) for p in parts]


def extract(field, lower, upper, step, newton_steps=NEWTON_STEPS):
    """Triangulate phi = 0 over the box [lower, upper] by marching tetrahedra.

    Parameters
    ----------
    field : callable
        field(points) with points (n, 3) returns (phi, grad, hess) of shapes (n,), (n, 3),
        (n, 3, 3); called with at most CHUNK points at once.
    lower, upper : array_like, shape (3,)
        The box; the grid starts at `lower` and has spacing `step`, with enough points to
        reach `upper` (it may end up to one step beyond).
    step : float
        Grid spacing. It must resolve the shape (two sheets less than a step apart may merge
        or vanish) but need not resolve a tanh profile: the vertices are found on the grid
        edges by bracketing.
    newton_steps : int
        Projections x <- x - phi grad / |grad|^2 after the edge root (halved while |phi| does
        not decrease); they move the vertices off their edges by little.

    Returns
    -------
    Surface
        Closed and manifold where phi < 0 on the box's sides; empty if phi has no sign change.
    """
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    step = float(step)
    shape = tuple(int(np.ceil((u - lo) / step - 1e-9)) + 1 for lo, u in zip(lower, upper))
    if min(shape) < 2:
        raise ValueError("the box must be at least one step wide")
    axes = [lo + step * np.arange(n) for lo, n in zip(lower, shape)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    phi = _call(field, grid, (0,))[0]
    inside = (phi > 0).reshape(shape)
    empty = Surface(np.zeros((0, 3)), np.zeros((0, 3), dtype=int), step)
    if inside.all() or not inside.any():
        return empty

    # Cells with a sign change among their 8 corners.
    nx, ny, nz = shape
    corners = [inside[i:nx - 1 + i, j:ny - 1 + j, k:nz - 1 + k]
               for i, j, k in itertools.product((0, 1), repeat=3)]
    anyin = np.logical_or.reduce(corners)
    allin = np.logical_and.reduce(corners)
    cells = np.argwhere(anyin & ~allin)
    origin = np.ravel_multi_index(cells.T, shape)
    strides = np.array([ny * nz, nz, 1])
    flat = inside.ravel()

    keys = []
    for t, tet in enumerate(_TETS):
        nodes = origin[:, None] + tet @ strides                     # (ncells, 4)
        pattern = (flat[nodes] * (1 << np.arange(4))).sum(axis=1)
        # Global key of each tetrahedron edge: (its lower node) * 7 + offset code.
        edge_keys = np.stack([nodes[:, i] * 7 + _OFFSET_CODE[tuple(tet[j] - tet[i])]
                              for i, j in _PAIRS], axis=1)          # (ncells, 6)
        for s in range(2):
            local = _TABLE[t, pattern, s]                           # (ncells, 3)
            has = local[:, 0] >= 0
            keys.append(np.take_along_axis(edge_keys[has], local[has], axis=1))
    keys = np.concatenate(keys)
    unique, triangles = np.unique(keys, return_inverse=True)
    triangles = triangles.reshape(-1, 3)

    a = unique // 7
    b = a + np.array(_OFFSETS)[unique % 7] @ strides
    swap = phi[a] <= 0   # the root finder wants the inside end first
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    vertices = _edge_roots(field, grid[a], grid[b], phi[a], phi[b])
    vertices = _project(field, vertices, newton_steps)
    return Surface(vertices, triangles, step)


def _edge_roots(field, xa, xb, fa, fb):
    """The zero of phi on each segment [xa, xb] (fa > 0 >= fb) by regula falsi (the value
    at an end kept twice in a row halved, so both ends move), the parameter kept in
    [TMIN, 1 - TMIN]."""
    lo, hi = np.zeros(len(xa)), np.ones(len(xa))
    flo, fhi = fa.copy(), fb.copy()
    t = np.clip(flo / (flo - fhi), TMIN, 1 - TMIN)
    side = np.zeros(len(xa), dtype=int)   # which end was kept last: +1 lo, -1 hi
    active = np.ones(len(xa), dtype=bool)
    for _ in range(EDGE_ITERATIONS):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        f = _call(field, xa[idx] + t[idx, None] * (xb[idx] - xa[idx]), (0,))[0]
        pos = f > 0
        # Replace the end of the same sign; halve the value kept twice.
        i, j = idx[pos], idx[~pos]
        lo[i], flo[i] = t[i], f[pos]
        fhi[i] = np.where(side[i] == 1, 0.5 * fhi[i], fhi[i])
        side[i] = 1
        hi[j], fhi[j] = t[j], f[~pos]
        flo[j] = np.where(side[j] == -1, 0.5 * flo[j], flo[j])
        side[j] = -1
        done = (hi[idx] - lo[idx] < EDGE_TOL) | (f == 0)
        t[idx] = lo[idx] + flo[idx] / (flo[idx] - fhi[idx]) * (hi[idx] - lo[idx])
        t[idx[f == 0]] = np.where(pos, lo[idx], hi[idx])[f == 0]
        active[idx[done]] = False
    t = np.clip(t, TMIN, 1 - TMIN)
    return xa + t[:, None] * (xb - xa)


def _project(field, x, steps):
    """Newton steps x <- x - phi grad / |grad|^2, halved (up to 10 times) until |phi|
    decreases: a steep tanh profile sends the full step far off from a point not yet on it."""
    x = x.copy()
    if not len(x):
        return x
    phi, grad = _call(field, x, (0, 1))
    for _ in range(steps):
        g2 = np.maximum(np.sum(grad ** 2, axis=1), np.finfo(float).tiny)
        move = (phi / g2)[:, None] * grad
        scale = np.ones(len(x))
        todo = np.flatnonzero(np.abs(phi) > PROJECT_TOL)
        for _ in range(10):
            if not todo.size:
                break
            trial = x[todo] - scale[todo, None] * move[todo]
            f, g = _call(field, trial, (0, 1))
            better = np.abs(f) < np.abs(phi[todo])
            accept = todo[better]
            x[accept], phi[accept], grad[accept] = trial[better], f[better], g[better]
            todo = todo[~better]
            scale[todo] *= 0.5
    return x


def _edges(triangles):
    """Sorted vertex pairs of the triangles' sides, shape (3 nt, 2), side s of triangle t at
    row 3 t + s."""
    sides = triangles[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    return np.sort(sides, axis=1)


def components(surface):
    """The connected components of a surface (through shared edges), largest area first.

    Returns
    -------
    list of Component
        Area, signed volume, Euler characteristic, genus, closedness, orientation and the
        enclosing component (`Component.parent`, an index into this list).
    """
    tri = surface.triangles
    if not len(tri):
        return []
    sides = _edges(tri)
    edge_ids, inverse, counts = np.unique(sides, axis=0, return_inverse=True,
                                          return_counts=True)
    inverse = inverse.ravel()
    owner = np.repeat(np.arange(len(tri)), 3)
    order = np.argsort(inverse, kind="stable")
    same = inverse[order][1:] == inverse[order][:-1]
    i, j = owner[order][:-1][same], owner[order][1:][same]
    graph = coo_matrix((np.ones(i.size), (i, j)), shape=(len(tri), len(tri)))
    n, labels = connected_components(graph, directed=False)

    v = surface.vertices
    p0, p1, p2 = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
    cross = np.cross(p1 - p0, p2 - p0)
    areas = 0.5 * np.linalg.norm(cross, axis=1)
    volumes = np.einsum("ij,ij->i", p0, np.cross(p1, p2)) / 6.0
    side_label = labels[owner]
    found = []
    for c in range(n):
        mine = np.flatnonzero(labels == c)
        edges_c = np.unique(inverse[side_label == c])
        verts = np.unique(tri[mine])
        chi = int(verts.size - edges_c.size + mine.size)
        closed = bool(np.all(counts[edges_c] == 2))
        volume = float(volumes[mine].sum())
        found.append(Component(mine, float(areas[mine].sum()), volume, chi,
                               (2 - chi) / 2 if closed else np.nan, closed,
                               1 if volume > 0 else -1))
    found.sort(key=lambda comp: -comp.area)
    _nesting(surface, found)
    return found


def _winding(point, vertices, triangles):
    """Winding number of a closed oriented triangulation about a point (the triangles' solid
    angles seen from it, 2 atan2(a . b x c, ...) each, summed over 4 pi)."""
    a, b, c = (vertices[triangles[:, i]] - point for i in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
           + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb)
    return float(np.sum(2.0 * np.arctan2(det, den)) / (4.0 * np.pi))


def _nesting(surface, found):
    """Set each component's parent: the closed component of smallest |volume| about which
    one of its vertices has winding number +-1."""
    for i, comp in enumerate(found):
        point = surface.vertices[surface.triangles[comp.triangles[0], 0]]
        best = None
        for j, other in enumerate(found):
            if j == i or not other.closed:
                continue
            tri = surface.triangles[other.triangles]
            if abs(_winding(point, surface.vertices, tri)) > 0.5:
                if best is None or abs(other.volume) < abs(found[best].volume):
                    best = j
        comp.parent = best


def mean_curvature(grad, hess):
    """H for the outward normal n = -grad phi / |grad phi| from grad phi and its Hessian.

    H = div(n) / 2 = -(|g|^2 tr(Hs) - g^T Hs g) / (2 |g|^3): +1/R on a sphere holding
    phi > 0 (phi = R - |x|: g = -x/|x|, div(g/|g|) = -2/|x|), -1/b on the inner sphere of a
    shell with phi > 0 between the spheres.
    """
    g2 = np.sum(grad ** 2, axis=1)
    trace = np.trace(hess, axis1=1, axis2=2)
    ghg = np.einsum("ni,nij,nj->n", grad, hess, grad)
    return -(g2 * trace - ghg) / (2.0 * g2 ** 1.5)


def triangle_areas(surface):
    """The flat area of each triangle."""
    v, tri = surface.vertices, surface.triangles
    return 0.5 * np.linalg.norm(np.cross(v[tri[:, 1]] - v[tri[:, 0]],
                                         v[tri[:, 2]] - v[tri[:, 0]]), axis=1)


def vertex_curvature(surface, field):
    """(H, weights): `mean_curvature` at the surface's vertices (the field's
    derivatives there) and each vertex's share of the area, a third of each of
    its triangles'."""
    _, grad, hess = _call(field, surface.vertices)
    area = triangle_areas(surface)
    weights = np.zeros(len(surface.vertices))
    for corner in range(3):
        np.add.at(weights, surface.triangles[:, corner], area / 3.0)
    return mean_curvature(grad, hess), weights


def helfrich_energy(surface, field, k=1.0, c0=0.0, parts=None):
    """E = (k/2) int (H - c0)^2 dS over the surface, in all and per component.

    H at the vertices from `mean_curvature` (the field's gradient and Hessian there), the
    integrand averaged over each triangle's vertices times its flat area.

    Parameters
    ----------
    surface : Surface
    field : callable
        As for `extract`.
    k : float
        Bending rigidity.
    c0 : float
        Spontaneous curvature C0, the checkpoint attribute ``c0`` as `levelset` uses it (see
        the module docstring): an inverse length, H - c0 in the integrand.
    parts : list of Component, optional
        `components(surface)`, if the caller has it.

    Returns
    -------
    Energy
        ``per_component`` in the order of `parts` (largest area first by default).
    """
    parts = components(surface) if parts is None else parts
    if not len(surface.triangles):
        return Energy(0.0, [])
    _, grad, hess = _call(field, surface.vertices)
    integrand = (mean_curvature(grad, hess) - c0) ** 2
    per_triangle = 0.5 * k * triangle_areas(surface) * integrand[surface.triangles].mean(axis=1)
    per = [float(per_triangle[p.triangles].sum()) for p in parts]
    return Energy(float(per_triangle.sum()), per)


def measure(field, lower, upper, step, k=1.0, c0=0.0):
    """`extract`, `components` and `helfrich_energy` in one call.

    Returns
    -------
    Measurement
        ``per_component`` holds dicts (triangles, area, volume, chi, genus, orientation,
        parent, energy); ``genus`` sums the closed components' genera (NaN if one is open),
        ``volume`` their signed volumes (a hole counts negative: the volume of phi > 0).
    """
    surface = extract(field, lower, upper, step)
    parts = components(surface)
    energy = helfrich_energy(surface, field, k, c0, parts)
    per = [dict(triangles=p.count, area=p.area, volume=p.volume, chi=p.chi, genus=p.genus,
                closed=p.closed, orientation=p.orientation, parent=p.parent, energy=e)
           for p, e in zip(parts, energy.per_component)]
    return Measurement(energy.total, float(sum(p.area for p in parts)),
                       float(sum(p.volume for p in parts)), len(parts),
                       float(sum(p.genus for p in parts)), per, surface)
