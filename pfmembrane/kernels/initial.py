"""Initial guesses with the scene's area and volume, tanh profiles of signed
distances: spheroids, tori, two spheres on the axis, and the surface of a
given generating curve (a sharp-interface shape)."""
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq
from scipy.spatial import cKDTree

PEAR_RATIO = 0.7  # the pear's start: two spheres of this radius ratio
CLIFFORD = np.sqrt(2.0)  # the Clifford torus: centre-line radius over tube radius
# The Moebius torus start inverts about (d, 0, 0), d up to this (the hole's edge is at
# sqrt 2 - 1 = 0.414, where the image becomes unbounded).
MOEBIUS_D_MAX = 0.35
# The rounding of a curve's distance at the axis, in resampling spacings: the sharp starts
# resample every eps / 32 (api.CURVE_SPACING), so over eps / 2.
AXIS_ROUNDING = 16


def reduced_volume(area, volume):
    """v = V / (4/3 pi R^3) with R = sqrt(A / 4 pi)."""
    return volume / (4.0 / 3.0 * np.pi * (area / (4.0 * np.pi)) ** 1.5)


def spheroid_area(a, c):
    """Area of the spheroid with equatorial semi-axis a and polar semi-axis c."""
    if np.isclose(a, c, rtol=1e-12):
        return 4.0 * np.pi * a * a
    if c < a:
        e = np.sqrt(1.0 - (c / a) ** 2)
        return 2.0 * np.pi * a * a * (1.0 + (1.0 - e * e) / e * np.arctanh(e))
    e = np.sqrt(1.0 - (a / c) ** 2)
    return 2.0 * np.pi * a * a * (1.0 + c / (a * e) * np.arcsin(e))


def spheroid_axes(area, volume, branch):
    """Semi-axes (a, c) of the oblate (c < a) or prolate (c > a) spheroid.

    Raises ValueError when no spheroid has that area and volume (reduced
    volume above 1).
    """
    R = np.sqrt(area / (4.0 * np.pi))
    v = reduced_volume(area, volume)
    if v > 1.0 + 1e-12:
        raise ValueError(f"reduced volume {v:.6g} > 1: no closed surface has this area and volume")
    if v >= 1.0 - 1e-12:
        return R, R

    def mismatch(t):  # t = c / a; volume fixes a for the given aspect ratio
        a = (3.0 * volume / (4.0 * np.pi * t)) ** (1.0 / 3.0)
        return spheroid_area(a, t * a) / area - 1.0

    t = brentq(mismatch, 1e-4, 1.0 - 1e-12) if branch == 'oblate' else brentq(mismatch, 1.0 + 1e-12, 1e4)
    a = (3.0 * volume / (4.0 * np.pi * t)) ** (1.0 / 3.0)
    return a, t * a


def spheroid_phi(points, a, c, zc, eps):
    """phi = tanh(d / (sqrt 2 eps)) with d the first-order signed distance
    to the spheroid (r/a)^2 + ((z - zc)/c)^2 = 1, positive inside."""
    r, z = points[:, 0], points[:, 1] - zc
    F = (r / a) ** 2 + (z / c) ** 2 - 1.0
    grad = 2.0 * np.hypot(r / a ** 2, z / c ** 2)
    d = -F / np.maximum(grad, 1e-300)
    # Far from the surface the linearization overshoots; the sign is what matters there.
    d = np.clip(d, -min(a, c), min(a, c))
    return np.tanh(d / (np.sqrt(2.0) * eps))


def ellipsoid_phi(points, axes, eps):
    """phi = tanh(d / (sqrt 2 eps)) of the ellipsoid of semi-axes `axes` along
    x, y, z about the origin at 3D `points` (n x 3), d its first-order
    signed distance, positive inside (as `spheroid_phi`)."""
    q = points / np.asarray(axes)
    F = np.einsum('ij,ij->i', q, q) - 1.0
    grad = 2.0 * np.linalg.norm(q / np.asarray(axes), axis=1)
    d = np.clip(-F / np.maximum(grad, 1e-300), -min(axes), min(axes))
    return np.tanh(d / (np.sqrt(2.0) * eps))


def harmonic_coefficients(points, field, harmonics, floor, samples=8):
    """Nodal chi_j of a 3D `field` (a function of n x 3 points): at each
    (r, z) of `points` the mean of field T_j over `samples` (J + 1) angles of
    one period, over the mean of T_j^2, divided by r^m (r at least `floor`:
    a smooth field's harmonics m > 0 vanish on the axis). Returns
    (n, nh)."""
    theta = (2 * np.pi / harmonics.dihedral) * np.arange(samples * (harmonics.highest + 1)) \
        / (samples * (harmonics.highest + 1))
    r, z = points[:, 0], points[:, 1]
    xyz = np.stack([np.outer(r, np.cos(theta)), np.outer(r, np.sin(theta)),
                    np.outer(z, np.ones_like(theta))], axis=-1)
    f = field(xyz.reshape(-1, 3)).reshape(len(points), len(theta))
    mt = np.outer(theta, harmonics.m)
    T = np.where(harmonics.sine, np.sin(mt), np.cos(mt))
    c = f @ T / (T * T).sum(axis=0)
    return c / np.maximum(r, floor)[:, None] ** harmonics.m


class Cyclide(NamedTuple):
    """A Moebius image of the Clifford torus (`moebius_torus`), sampled:
    `points` and unit outward `normals` on it, and the map back to the
    Clifford torus, point -> centre + (point / scale + (hole, 0, 0) -
    centre) / |...|^2, centre = (d, 0, 0)."""
    points: np.ndarray
    normals: np.ndarray
    d: float
    scale: float
    hole: float
    tree: cKDTree


def _inverted_clifford(d, n):
    """The unit inversion about (d, 0, 0) of the Clifford torus of tube radius
    1 round the circle of radius sqrt 2 in z = 0, on n x n points of its two
    angles: points Y and area vectors Y_u x Y_w (outward), area, volume."""
    u = 2 * np.pi * np.arange(n) / n
    U, W = np.meshgrid(u, u, indexing='ij')
    rr = CLIFFORD + np.cos(U)
    X = np.stack([rr * np.cos(W), rr * np.sin(W), np.sin(U)], axis=-1)
    Xu = np.stack([-np.sin(U) * np.cos(W), -np.sin(U) * np.sin(W), np.cos(U)], axis=-1)
    Xw = np.stack([-rr * np.sin(W), rr * np.cos(W), np.zeros_like(U)], axis=-1)
    D = X - [d, 0.0, 0.0]
    q = np.einsum('...i,...i', D, D)[..., None]
    # the inversion's differential: (I - 2 D D^T / |D|^2) / |D|^2
    J = lambda T: T / q - 2 * D * np.einsum('...i,...i', D, T)[..., None] / q ** 2  # noqa: E731
    Y = [d, 0.0, 0.0] + D / q
    N = np.cross(J(Xu), J(Xw))
    h2 = (2 * np.pi / n) ** 2   # the periodic trapezoid rule: spectral accuracy
    volume = np.einsum('...i,...i', Y, N).sum() * h2 / 3
    N = N * np.sign(volume)     # an inversion reverses the orientation
    return Y.reshape(-1, 3), N.reshape(-1, 3), np.linalg.norm(N, axis=-1).sum() * h2, \
        abs(volume)


def _moebius_reduced(d):
    """The reduced volume of the Clifford torus inverted about (d, 0, 0)."""
    return reduced_volume(*_inverted_clifford(d, 128)[2:])


@lru_cache(maxsize=None)
def moebius_range():
    """(low, high): the reduced volumes of the Moebius images `moebius_torus`
    builds, the Clifford torus's 0.71164 to that at MOEBIUS_D_MAX."""
    return _moebius_reduced(0.0), _moebius_reduced(MOEBIUS_D_MAX)


def moebius_torus(area, volume, samples=256):
    """The Moebius image of the Clifford torus with this area and volume: the
    unit inversion about (d, 0, 0) inside its hole (d = 0 the Clifford torus,
    reduced volume 0.71164; up to 0.93 at d = 0.3), scaled to the area,
    placed with the centre of its hole (the image of the outer equator) on
    the axis and its mirror plane z = 0. A non-axisymmetric torus whose
    Willmore energy stays 2 pi^2: E = pi^2 k at C0 = 0 (Marques and Neves).
    Raises ValueError for reduced volumes outside (0.7117, 0.98)."""
    v = reduced_volume(area, volume)
    low, high = moebius_range()
    if not low < v < high:
        raise ValueError(f"reduced volume {v:.6g} outside ({low:.5g}, {high:.5g}), the Moebius "
                         "images of the Clifford torus inverted inside its hole")
    d = brentq(lambda t: _moebius_reduced(t) - v, 0.0, MOEBIUS_D_MAX, xtol=1e-14)
    Y, N, A, _ = _inverted_clifford(d, samples)
    scale = np.sqrt(area / A)
    outer = CLIFFORD + 1.0
    hole = d + 0.5 * (1.0 / (outer - d) - 1.0 / (outer + d))
    points = scale * (Y - [hole, 0.0, 0.0])
    normals = N / np.linalg.norm(N, axis=1)[:, None]
    return Cyclide(points, normals, d, scale, hole, cKDTree(points))


def moebius_phi(points, cyclide, eps):
    """phi = tanh(d / (sqrt 2 eps)) of a `Cyclide` at 3D `points` (n x 3):
    |d| the distance to the nearest sample's tangent plane (second order in
    the samples' spacing), its sign that of the point's preimage (inside the
    Clifford torus: positive)."""
    _, i = cyclide.tree.query(points)
    distance = np.abs(np.einsum('ij,ij->i', points - cyclide.points[i], cyclide.normals[i]))
    c = np.array([cyclide.d, 0.0, 0.0])
    D = points / cyclide.scale + [cyclide.hole, 0.0, 0.0] - c
    P = c + D / np.einsum('ij,ij->i', D, D)[:, None]
    inside = np.hypot(np.hypot(P[:, 0], P[:, 1]) - CLIFFORD, P[:, 2]) < 1.0
    return np.tanh(np.where(inside, distance, -distance) / (np.sqrt(2.0) * eps))


def profile(d, eps):
    """The tanh profile phi = tanh(d / (sqrt 2 eps)) of a signed distance d."""
    return np.tanh(d / (np.sqrt(2.0) * eps))


def torus_radii(area, volume):
    """Tube radius a and centre-line radius b of the torus with this area
    (4 pi^2 a b) and volume (2 pi^2 a^2 b).

    Raises ValueError unless b > a (a ring torus, reduced volume below
    3 / (2 sqrt pi) = 0.846).
    """
    a = 2.0 * volume / area
    b = area / (4.0 * np.pi ** 2 * a)
    if not b > a:
        raise ValueError(f"no ring torus has this area and volume (tube radius {a:.4g} >= "
                         f"centre-line radius {b:.4g})")
    return a, b


def torus_distance(points, a, b, zc):
    """Signed distance to the torus of tube radius a round the circle r = b,
    z = zc, positive inside."""
    return a - np.hypot(points[:, 0] - b, points[:, 1] - zc)


def _spheres(rho1, rho2, D):
    """Area, volume and centroid height of the union of two spheres on the
    axis, radii rho1 (centre z = 0) and rho2 (centre z = D), that overlap
    (rho1 - rho2 < D <= rho1 + rho2): zones of each sphere beyond the plane
    z* where they meet."""
    zs = (D * D + rho1 * rho1 - rho2 * rho2) / (2.0 * D)
    us = zs - D  # z* from the second centre
    area = 2.0 * np.pi * (rho1 * (zs + rho1) + rho2 * (rho2 - us))
    cap1 = lambda t: np.pi * (rho1 ** 2 * t - t ** 3 / 3.0)  # int pi (rho^2 - t^2) dt
    cap2 = lambda u: np.pi * (rho2 ** 2 * u - u ** 3 / 3.0)
    moment = lambda rho, t: np.pi * (rho ** 2 * t ** 2 / 2.0 - t ** 4 / 4.0)
    volume = cap1(zs) - cap1(-rho1) + cap2(rho2) - cap2(us)
    first = moment(rho1, zs) - moment(rho1, -rho1)
    second = moment(rho2, rho2) - moment(rho2, us) + D * (cap2(rho2) - cap2(us))
    return area, volume, (first + second) / volume


def two_spheres(area, volume, ratio=1.0):
    """Radii (rho1, rho2 = ratio rho1 <= rho1) and centre heights, relative to
    the volume centroid, of two overlapping (or touching) spheres on the axis
    whose union has this area and volume.

    Two touching spheres enclose the least volume: raises ValueError below
    reduced volume (1 + ratio^3) / (1 + ratio^2)^(3/2) (1/sqrt 2 for equal
    spheres).
    """
    R = np.sqrt(area / (4.0 * np.pi))
    lo = R / np.sqrt(1.0 + ratio ** 2)  # touching spheres
    touching = _spheres(lo, ratio * lo, (1.0 + ratio) * lo)[1]
    if volume < touching * (1.0 - 1e-12):
        raise ValueError(f"two spheres of radius ratio {ratio:g} enclose at least reduced volume "
                         f"{reduced_volume(area, touching):.5g}")

    def separation(rho1):  # the distance of the centres that gives the area
        rho2 = ratio * rho1
        near = max(rho1 - rho2, 0.0) + 1e-12 * rho1
        far = rho1 + rho2
        if _spheres(rho1, rho2, far)[0] <= area:
            return far
        return brentq(lambda D: _spheres(rho1, rho2, D)[0] - area, near, far, xtol=1e-15)

    if volume <= touching:
        rho1 = lo
    else:
        rho1 = brentq(lambda rho: _spheres(rho, ratio * rho, separation(rho))[1] - volume,
                      lo, R * (1.0 - 1e-9), xtol=1e-15)
    D = separation(rho1)
    centroid = _spheres(rho1, ratio * rho1, D)[2]
    return np.array([rho1, ratio * rho1]), np.array([-centroid, D - centroid])


def tanh_sphere(rho, eps):
    """The phase-field area and volume (`A[phi]`, `V[phi]` of the model) of the tanh
    profile of a sphere of radius rho >> eps: 4 pi (rho^2 + (pi^2 - 6) eps^2 / 6) and
    4/3 pi rho^3 + 2/3 pi^3 rho eps^2, exact but for terms in exp(-rho / eps)."""
    area = 4.0 * np.pi * (rho * rho + (np.pi ** 2 - 6.0) * eps * eps / 6.0)
    return area, 4.0 / 3.0 * np.pi * rho ** 3 + 2.0 / 3.0 * np.pi ** 3 * rho * eps * eps


def spheres_distance(points, radii, heights, zc):
    """Signed distance to the union of spheres centred on the axis at zc +
    heights, positive inside (exact outside and in each sphere away from the
    others)."""
    centres = np.column_stack([np.zeros_like(heights), zc + np.asarray(heights)])
    return np.max([rho - np.hypot(*(points - c).T) for rho, c in zip(radii, centres)], axis=0)


def curve_distance(points, r, z, spacing):
    """Signed distance, positive inside, to the surface of revolution of the
    generating curve (r, z) that runs from the axis (r = 0) to the axis.

    The distance to the nearest point of the curve and its mirror image about
    r = 0, resampled every `spacing` (error below spacing / 2 on the curve,
    spacing^2 / (8 d) at a distance d), rounded within AXIS_ROUNDING spacings of
    the axis; inside by the even-odd rule on that closed polygon.
    """
    polygon = np.concatenate([np.column_stack([r, z]), np.column_stack([-r, z])[::-1]])
    polygon = np.vstack([polygon, polygon[:1]])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(polygon, axis=0).T))])
    t = np.linspace(0.0, s[-1], int(np.ceil(s[-1] / spacing)) + 1)
    fine = np.column_stack([np.interp(t, s, polygon[:, 0]), np.interp(t, s, polygon[:, 1])])
    tree = cKDTree(fine)
    d = tree.query(points)[0]
    # On the axis inside a channel of the curve (a stomatocyte's neck) the distance to
    # the ring of the channel has a conical kink, d = |r| - a, whose Laplacian 1/r puts
    # a spurious (logarithmically divergent) W^2 on the axis: there r is replaced by
    # (r^2 + w^2) / (2 w), smooth and even, C1 at r = w.
    w = AXIS_ROUNDING * spacing
    near = np.flatnonzero(points[:, 0] < w)
    lifted = np.column_stack([(points[near, 0] ** 2 + w * w) / (2 * w), points[near, 1]])
    # in full across the interface (8 w = 4 eps), fading where the profile has saturated
    weight = np.exp(-np.maximum(d[near] / w - 8.0, 0.0) ** 2)
    d[near] += weight * (tree.query(lifted)[0] - d[near])
    return np.where(_inside(points, polygon), d, -d)


def _inside(points, polygon):
    """Even-odd rule: whether each point is inside the closed polygon (first
    vertex repeated last), by the crossings of a ray towards +r. Each edge
    meets only the points of its band of z, found in the points sorted by z."""
    order = np.argsort(points[:, 1])
    z = points[order, 1]
    crossings = np.zeros(len(points), dtype=int)
    for (r1, z1), (r2, z2) in zip(polygon[:-1], polygon[1:]):
        if z1 == z2:  # a horizontal edge crosses no ray
            continue
        # The half-open band min <= z < max counts a vertex shared by two edges once.
        lo, hi = np.searchsorted(z, sorted((z1, z2)))
        band = order[lo:hi]
        at = r1 + (points[band, 1] - z1) * (r2 - r1) / (z2 - z1)
        crossings[band] += points[band, 0] < at
    return crossings % 2 == 1


def construction(kind, branch, area, volume):
    """The shape of a constructed start of the family `branch`: a 'spheroid'
    (semi-axes a, c), a 'torus' (radii a, b) or two 'spheres' (radii, heights;
    equal but for the pear). Raises ValueError when it cannot have this area
    and volume."""
    if kind in ('spheroid', 'across'):
        return spheroid_axes(area, volume, branch)
    if kind == 'torus':
        return torus_radii(area, volume)
    if kind == 'moebius':
        return moebius_torus(area, volume)
    return two_spheres(area, volume, pear_ratio(area, volume) if branch == 'pear' else 1.0)


def pear_ratio(area, volume):
    """The pear's radius ratio: PEAR_RATIO, or where two touching spheres of that ratio
    enclose more than `volume` (reduced volume below 0.7384), the ratio whose touching
    spheres enclose it (1 at 1/sqrt 2, below which no two spheres do)."""
    v = reduced_volume(area, volume)
    touching = lambda q: (1.0 + q ** 3) / (1.0 + q * q) ** 1.5  # noqa: E731
    if v >= touching(PEAR_RATIO) or v < touching(1.0):
        return PEAR_RATIO
    return brentq(lambda q: touching(q) - v, PEAR_RATIO, 1.0, xtol=1e-14)


def extent(kind, shape):
    """Half-sizes (largest r, largest |z - zc|) of a start: `kind` 'spheroid'
    (semi-axes a, c), 'torus' (radii a, b), 'spheres' (radii, heights) or
    'sharp' (its generating curve r, z about the centroid)."""
    if kind == 'spheroid':
        return tuple(shape)
    if kind == 'across':  # the long axis c along x
        return shape[1], shape[0]
    if kind == 'torus':
        a, b = shape
        return a + b, a
    if kind == 'moebius':
        p = shape.points
        return float(np.hypot(p[:, 0], p[:, 1]).max()), float(np.abs(p[:, 2]).max())
    if kind == 'spheres':
        radii, heights = shape
        return float(np.max(radii)), float(np.max(np.abs(heights) + radii))
    r, z = shape
    return float(np.max(r)), float(np.max(np.abs(z)))


def rescaled_phi(phi, eps_from, eps_to):
    """A solved field for eps_from as a start for eps_to: the tanh profile
    phi = tanh(d / (sqrt 2 eps)) narrowed or widened about the same level set.

    Unchanged at |phi| >= 1 (the imposed -1, overshoots). The old profile,
    too wide for a smaller eps_to, leaves the Newton iteration a longer way.
    """
    phi = np.array(phi, dtype=float)
    if eps_from == eps_to:  # a restart at its own eps continues bit for bit
        return phi
    inside = np.abs(phi) < 1.0
    phi[inside] = np.tanh(np.arctanh(phi[inside]) * (eps_from / eps_to))
    return phi
