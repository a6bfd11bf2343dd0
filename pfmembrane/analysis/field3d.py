"""The 3D field phi_h(x, y, z) of a result with azimuthal harmonics, and the
measures of its zero level set (`analysis.surface`).

Not collective. phi_h = sum_j r^m_j chi_j(r, z) T_j(theta) (`kernels.harmonics`).
Each chi_j is evaluated once with the max-ent basis on an (r, z) raster, mirrored
to r < 0 as the basis is even in r (so chi_r = 0 on the axis), and fitted by a
bicubic interpolating spline; the field, its gradient and its Hessian at any 3D
point then cost a few spline evaluations. The raster's step is a sixth of eps:
the spline's error on a tanh profile of width sqrt2 eps is then far below the
max-ent field's own (checked against the basis at the raster's midpoints).
"""
from dataclasses import dataclass
import itertools

import numpy as np
from scipy.interpolate import RectBivariateSpline

from pfmembrane.analysis import surface
from pfmembrane.io import checkpoint
from pfmembrane.kernels.basis import folded_basis
from pfmembrane.kernels.initial import reduced_volume
from pfmembrane.kernels.maxent import interpolate

RASTER = 1.0 / 6      # raster step, in eps
MARCH = 0.5           # marching-tetrahedra step, in eps
R_AXIS = 1e-9         # 1/r terms are taken at r >= R_AXIS (their limits are finite)
LEVEL_TOL = 1e-6      # reduced volume of the projected level set, off v by at most this
RADIAL_DEGREE = 4     # the projection's displacement: a polynomial of this degree in the direction
SAMPLE_STEP = 0.5     # a checkpoint's phi3d: its step, in eps ...
SAMPLE_POINTS = 2_000_000  # ... coarsened to keep it at most this many points


@dataclass
class Harmonic3D:
    """phi_h of nodal harmonics `phi` (nodes x nh) with orders `m` and sine
    flags `sine`, zc the scene's centre height and `plane` its mirror plane
    (a half box) or None."""
    splines: list
    m: np.ndarray
    sine: np.ndarray
    zc: float
    plane: float = None
    extent: tuple = None   # (largest r, lowest z, highest z) where phi_h may reach 0

    @classmethod
    def of(cls, nodes, phi, m, sine, box, eps, beta, cutoff, plane=None):
        z0 = plane if plane is not None else 0.0
        # steps of at most RASTER eps that end on the box's sides
        r, z = (np.linspace(a, b, int(np.ceil((b - a) / (RASTER * eps))) + 1)
                for a, b in ((0.0, box[0]), (z0, box[1])))
        R, Z = np.meshgrid(r, z, indexing='ij')
        points = np.column_stack([R.ravel(), Z.ravel()])
        basis = folded_basis(points, nodes, beta, cutoff, derivatives=0, plane=plane)
        values = interpolate(basis, np.reshape(phi, (len(nodes), -1)))
        full_r = np.concatenate([-r[:0:-1], r])
        splines = []
        for j in range(values.shape[1]):
            v = values[:, j].reshape(len(r), len(z))
            splines.append(RectBivariateSpline(full_r, z, np.concatenate([v[:0:-1], v]),
                                               kx=3, ky=3, s=0))
        # phi_h <= chi_0 + sum_j>0 r^m |chi_j|: where that bound is below 0 there is no membrane
        bound = values[:, 0] + (np.abs(values[:, 1:]) * points[:, :1] ** np.asarray(m)[1:]).sum(1)
        near = points[bound >= -0.5]
        extent = None
        if len(near):
            zlo = near[:, 1].min() if plane is None else 2 * plane - near[:, 1].max()
            extent = (near[:, 0].max(), zlo, near[:, 1].max())
        return cls(splines, np.asarray(m), np.asarray(sine, bool), 0.5 * box[1], plane, extent)

    def __call__(self, points):
        return _Evaluation(self, np.asarray(points, dtype=float))

    def cylindrical(self, points):
        """r, theta, z (z mirrored into the half box) and the mirror's sign
        of d/dz."""
        x, y, z = points.T
        flip = np.ones_like(z)
        if self.plane is not None:
            below = z < self.plane
            z = np.where(below, 2 * self.plane - z, z)
            flip = np.where(below, -1.0, 1.0)
        return np.hypot(x, y), np.arctan2(y, x), z, flip


class _Evaluation:
    """(phi, grad, hess) at points, each computed when first asked for, to the
    order asked (the level set's sampling needs phi alone, its projection the
    gradient, its curvature the Hessian)."""

    def __init__(self, field, points):
        self.f, self.points = field, points
        self._parts = ()

    def __getitem__(self, i):
        if i >= len(self._parts):
            self._parts = self._phi() if i == 0 else self._derivatives(i)
        return self._parts[i]

    def _phi(self):
        f = self.f
        r, theta, z, _ = f.cylindrical(self.points)
        out = np.zeros(len(r))
        for s, m, sine in zip(f.splines, f.m, f.sine):
            T = np.sin(m * theta) if sine else np.cos(m * theta)
            out += r ** m * s.ev(r, z) * T
        return (out,)

    def _derivatives(self, order):
        """phi, its Cartesian gradient and, to `order` 2, its Hessian, from the
        cylindrical derivatives f_r, f_theta, f_z (and f_rr, f_rtheta,
        f_thetatheta, f_rz, f_thetaz, f_zz) of sum_j g_j(r, z) T_j(theta),
        g_j = r^m S_j."""
        f = self.f
        r, theta, z, flip = f.cylindrical(self.points)
        r = np.maximum(r, R_AXIS)
        n = len(r)
        F = {k: np.zeros(n) for k in ('', 'r', 't', 'z', 'rr', 'rt', 'tt', 'rz', 'tz', 'zz')}
        for s, m, sine in zip(f.splines, f.m, f.sine):
            S, Sr, Sz = s.ev(r, z), s.ev(r, z, dx=1), s.ev(r, z, dy=1)
            rm = r ** m
            rm1 = m * r ** (m - 1.0) if m else np.zeros(n)
            g, gr, gz = rm * S, rm1 * S + rm * Sr, rm * Sz
            c, sn = np.cos(m * theta), np.sin(m * theta)
            T, dT, d2T = (sn, m * c, -m * m * sn) if sine else (c, -m * sn, -m * m * c)
            terms = [('', g, T), ('r', gr, T), ('t', g, dT), ('z', gz, T)]
            if order > 1:
                Srr, Srz, Szz = s.ev(r, z, dx=2), s.ev(r, z, dx=1, dy=1), s.ev(r, z, dy=2)
                rm2 = m * (m - 1.0) * r ** (m - 2.0) if m > 1 else np.zeros(n)
                grr, grz, gzz = rm2 * S + 2 * rm1 * Sr + rm * Srr, rm1 * Sz + rm * Srz, rm * Szz
                terms += [('rr', grr, T), ('rt', gr, dT), ('tt', g, d2T), ('rz', grz, T),
                          ('tz', gz, dT), ('zz', gzz, T)]
            for key, a, b in terms:
                F[key] += a * b
        c, s = np.cos(theta), np.sin(theta)
        fr, ft, fz = F['r'], F['t'] / r, F['z'] * flip
        grad = np.column_stack([c * fr - s * ft, s * fr + c * ft, fz])
        if order == 1:
            return F[''], grad
        # d/dx = c d/dr - (s / r) d/dtheta, d/dy = s d/dr + (c / r) d/dtheta
        rr, rt, tt, fr_r, ft_r2 = F['rr'], F['rt'] / r, F['tt'] / r ** 2, F['r'] / r, \
            F['t'] / r ** 2
        xx = c * c * rr - 2 * c * s * rt + s * s * (tt + fr_r) + 2 * c * s * ft_r2
        yy = s * s * rr + 2 * c * s * rt + c * c * (tt + fr_r) - 2 * c * s * ft_r2
        xy = c * s * (rr - tt - fr_r) + (c * c - s * s) * (rt - ft_r2)
        xz = (c * F['rz'] - s * F['tz'] / r) * flip
        yz = (s * F['rz'] + c * F['tz'] / r) * flip
        zz = F['zz']
        hess = np.stack([np.column_stack([xx, xy, xz]), np.column_stack([xy, yy, yz]),
                         np.column_stack([xz, yz, zz])], axis=1)
        return F[''], grad, hess


def measure(field, box, eps, k, c0, step=None):
    """The zero level set of `field` (a `Harmonic3D`) in the cylinder of the
    box: `analysis.surface.measure` on a Cartesian grid of step `step`
    (MARCH eps by default, `_bounds`)."""
    step = step or MARCH * eps
    return surface.measure(field, *_bounds(field, box, eps, step), step, k=k, c0=c0)


def _bounds(field, box, eps, step, spare=0.0):
    """The marching grid's corners: the box's cylinder cut to the field's
    extent with 2 eps (and `spare`) to spare, the lower shifted by an
    irrational fraction of the step so that no sample lies on the axis."""
    f = getattr(field, 'field', field)  # a `_Moved` field
    Rb, Zb = box
    lower, upper = np.array([-Rb, -Rb, 0.0]), np.array([Rb, Rb, Zb])
    if f.extent is not None:
        r, zlo, zhi = f.extent
        d = 2 * eps + spare
        lower = np.maximum(lower, [-r - d, -r - d, zlo - d])
        upper = np.minimum(upper, [r + d, r + d, zhi + d])
    return lower + step * (np.sqrt(2) - 1) / 3, upper


def projected(field, box, eps, k, c0, radius, v, iterations=10):
    """The level set's energy put on the scene's constraints, as the
    axisymmetric one is (`levelset.level_set_energy`, the least change of the
    curve's tangent angle onto them). phi_h = 0 moves along its normal by
    delta = beta p: first p = 1, a shift of the level (beta G within +-0.9, G
    = 1 / (sqrt 2 eps) the tanh profile's slope at its zero); where no level
    has the scene's reduced volume (a near-sphere's hardly changes with a
    uniform move), p(omega) fits H - <H> on phi_h = 0 by polynomials of degree
    RADIAL_DEGREE in the direction omega from its centroid (`Radial`, largest
    |p| on it 1), because the least normal displacement that changes the
    reduced volume is, but for a dilation, along H - <H> (the L2 gradient of ln V
    / A^(3/2) is 1 / V - 3 H / A). beta (a length) gives the scene's reduced
    volume (secant steps on the coarse marching step), and the surface is
    scaled to the area 4 pi R^2 (scaling by s leaves (H - C0)^2 dS as (H - s
    C0)^2 dS, so its energy is that of the moved surface with C0 s). The moved
    surface is the zero set of phi_h - G beta p (`_Moved`), so its curvature
    comes from exact derivatives. The sharp shape is stationary on the
    constraints, so the error is second order in the distance to it. Measured
    at steps MARCH eps and half that. Returns the finer measurement's
    components, its energy and the change from the coarser step (the bar), and
    beta; NaN where neither move reaches the reduced volume within LEVEL_TOL
    or the moved surface is not one surface."""
    coarse_step = MARCH * eps
    surf = surface.extract(field, *_bounds(field, box, eps, coarse_step), coarse_step)
    if len(surface.components(surf)) != 1:
        return None, np.nan, np.nan, np.nan
    # the curvature fit (the field's Hessian at every vertex) only where no level will do
    for move, reach in ((lambda: _uniform, 0.9 / _slope(eps)),
                        (lambda: Radial.fit(surf, field), np.inf)):
        delta = move()
        beta = _onto(field, box, eps, delta, v, coarse_step, reach, iterations)
        if beta is not None:
            break
    else:
        return None, np.nan, np.nan, np.nan
    out = []
    for step in (coarse_step, coarse_step / 2):
        moved = _Moved(field, delta, beta, eps)
        surf = surface.extract(moved, *_bounds(field, box, eps, step, abs(beta)), step)
        parts = surface.components(surf)
        scale = np.sqrt(4 * np.pi * radius ** 2 / sum(p.area for p in parts))
        out.append((parts, surface.helfrich_energy(surf, moved, k, c0 * scale, parts).total))
    (_, coarse), (parts, energy) = out
    return parts, energy, abs(energy - coarse), beta


def _onto(field, box, eps, delta, v, step, reach, iterations):
    """The beta within +-reach whose move (`_Moved`) has the reduced volume v
    within LEVEL_TOL (secant steps from 0 and the level shift 0.05), or None."""
    def reduced(beta):
        # area and volume alone: the energy (the Hessian at every vertex) waits for beta
        parts = surface.components(surface.extract(_Moved(field, delta, beta, eps),
                                                   *_bounds(field, box, eps, step, abs(beta)),
                                                   step))
        if len(parts) != 1:
            return np.nan
        return reduced_volume(parts[0].area, parts[0].volume) - v
    beta = [0.0, 0.05 * np.sqrt(2.0) * eps]
    f = [reduced(b) for b in beta]
    for _ in range(iterations):
        if not np.isfinite(f[-1]) or abs(f[-1]) < 1e-10 or f[-1] == f[-2]:
            break
        beta.append(float(np.clip(beta[-1] - f[-1] * (beta[-1] - beta[-2]) / (f[-1] - f[-2]),
                                  -reach, reach)))
        f.append(reduced(beta[-1]))
    if not np.isfinite(f).any():
        return None
    best = int(np.nanargmin(np.abs(f)))
    return beta[best] if abs(f[best]) < LEVEL_TOL else None


def _slope(eps):
    """G = 1 / (sqrt 2 eps): the slope of the tanh profile at its zero."""
    return 1.0 / (np.sqrt(2.0) * eps)


def _uniform(points, order=2):
    """delta = 1 and its derivatives: the move that shifts the level."""
    n = len(points)
    return [np.ones(n), np.zeros((n, 3)), np.zeros((n, 3, 3))][:order + 1]


def _monomials(w, degree, order=2):
    """The monomials w_x^a w_y^b w_z^c, a + b + c <= degree, at the points w
    (n x 3): values (n, M), gradients (n, M, 3) and Hessians (n, M, 3, 3), the
    derivatives up to `order`."""
    e = np.array([t for t in itertools.product(range(degree + 1), repeat=3)
                  if sum(t) <= degree])

    def power(axis, d):
        # the d-th derivative of w_axis^e: e! / (e - d)! w^(e - d), 0 where d > e
        factor = np.ones(len(e))
        for j in range(d):
            factor = factor * (e[:, axis] - j)
        return factor * w[:, axis, None] ** np.maximum(e[:, axis] - d, 0)
    P = [[power(a, d) for d in range(order + 1)] for a in range(3)]
    value = P[0][0] * P[1][0] * P[2][0]
    if order == 0:
        return (value,)
    grad = np.stack([P[a][1] * P[(a + 1) % 3][0] * P[(a + 2) % 3][0] for a in range(3)], -1)
    if order == 1:
        return value, grad
    hess = np.empty(value.shape + (3, 3))
    for a in range(3):
        for b in range(3):
            if a == b:
                hess[..., a, a] = P[a][2] * P[(a + 1) % 3][0] * P[(a + 2) % 3][0]
            else:
                c = 3 - a - b
                hess[..., a, b] = P[a][1] * P[b][1] * P[c][0]
    return value, grad, hess


class Radial:
    """delta(x) = p(omega), omega = (x - x0) / |x - x0|, p a polynomial of
    degree RADIAL_DEGREE in omega's components (on the unit sphere, the
    spherical harmonics of degree up to RADIAL_DEGREE): constant along each
    ray from x0, so the level set it moves has one displacement per direction."""

    def __init__(self, coefficients, x0):
        self.coefficients, self.x0 = coefficients, x0

    @classmethod
    def fit(cls, surf, field):
        """H - <H> of the surface (`surface.vertex_curvature`) fitted by least
        squares weighted by the vertices' areas, about its area centroid,
        scaled to largest |p| 1 at the vertices."""
        H, weights = surface.vertex_curvature(surf, field)
        x0 = weights @ surf.vertices / weights.sum()
        Y = surf.vertices - x0
        B = _monomials(Y / np.linalg.norm(Y, axis=1)[:, None], RADIAL_DEGREE)[0]
        root = np.sqrt(weights)
        target = H - weights @ H / weights.sum()
        c = np.linalg.lstsq(B * root[:, None], target * root, rcond=None)[0]
        return cls(c / np.abs(B @ c).max(), x0)

    def __call__(self, points, order=2):
        """(delta, grad delta, Hessian of delta) at `points` (n x 3), up to
        `order`: with Q = I - omega omega^T and g the polynomial's derivatives
        at omega, grad = Q g' / rho and Hessian = (Q g'' Q - (Q g') omega^T -
        omega (Q g')^T - (omega . g') Q) / rho^2, rho = |x - x0|."""
        Y = points - self.x0
        rho = np.linalg.norm(Y, axis=1)
        w = Y / rho[:, None]
        g = [np.tensordot(t, self.coefficients, axes=(1, 0))
             for t in _monomials(w, RADIAL_DEGREE, order)]
        if order == 0:
            return g
        Q = np.eye(3) - np.einsum('ni,nj->nij', w, w)
        Qg = np.einsum('nij,nj->ni', Q, g[1])
        out = [g[0], Qg / rho[:, None]]
        if order == 2:
            wg = np.einsum('ni,ni->n', w, g[1])
            out.append((np.einsum('nij,njk,nkl->nil', Q, g[2], Q)
                        - np.einsum('ni,nj->nij', Qg, w) - np.einsum('ni,nj->nij', w, Qg)
                        - wg[:, None, None] * Q) / rho[:, None, None] ** 2)
        return out


class _Moved:
    """phi_h - G beta delta, G = 1 / (sqrt 2 eps): the zero level set moved
    along its normal by about beta delta."""

    def __init__(self, field, delta, beta, eps):
        self.field, self.delta, self.scale = field, delta, beta * _slope(eps)

    def __call__(self, points):
        return _Shifted(self.field(points), self.delta, points, self.scale)


class _Shifted:
    """`_Moved` at some points, each derivative computed when first asked for
    (the marching samples need the values alone)."""

    def __init__(self, value, delta, points, scale):
        self.value, self.delta, self.points, self.scale = value, delta, points, scale
        self.parts = []

    def __getitem__(self, i):
        if len(self.parts) <= i:
            self.parts = self.delta(self.points, i)
        return self.value[i] - self.scale * self.parts[i]


def of_checkpoint(ckpt, beta=None):
    """(phi_h, box, eps) of a checkpoint with harmonics. Not collective.
    `beta`: the basis's locality at the nodes, if the caller has it
    (`io.checkpoint.locality` otherwise)."""
    layout = checkpoint.harmonic_set(ckpt.attrs, ckpt.phi.shape[1])
    box, eps = ckpt.box, float(ckpt.attrs["eps"])
    if beta is None:
        beta = checkpoint.locality(ckpt.nodes, ckpt.attrs, ckpt.plane)
    return (Harmonic3D.of(ckpt.nodes, ckpt.phi, layout.m, layout.sine, box, eps, beta,
                          checkpoint.basis(ckpt.attrs)["cutoff"], ckpt.plane), box, eps)


def level_surface(ckpt, step=None):
    """The triangulated phi_h = 0 of a checkpoint with harmonics
    (`analysis.surface.extract`, the marching step MARCH eps by default), for
    pictures. Not collective."""
    field_h, box, eps = of_checkpoint(ckpt)
    step = step or MARCH * eps
    return surface.extract(field_h, *_bounds(field_h, box, eps, step), step)


def sample(nodes, phi, attrs, beta=None):
    """phi_h of nodal harmonics `phi` (N x nh, with their checkpoint
    attributes `attrs`) on the Cartesian grid of the box: x, y in [-Rb, Rb], z
    in [0, Zb] (the mirror image of a half box included), steps near
    SAMPLE_STEP eps, coarsened to at most SAMPLE_POINTS points.

    Not collective. `beta`: the basis's locality at the nodes, if the caller
    has it (`io.checkpoint.locality` otherwise). phi_h is `Harmonic3D`'s;
    beyond the cylinder r = Rb its splines hold their values at r = Rb, where
    phi_h = -1.

    Returns
    -------
    values : ndarray, shape (nz, ny, nx)
        phi_h at origin + (i, j, k) * step in values[k, j, i].
    origin, step : ndarray, shape (3,)
        (x, y, z) of the first point and the steps along x, y, z.
    """
    field_h, box, eps = of_checkpoint(checkpoint.Checkpoint(nodes, phi, attrs), beta)
    origin = np.array([-box[0], -box[0], 0.0])
    lengths = np.array([2.0 * box[0], 2.0 * box[0], box[1]])
    counts = _sample_counts(lengths, SAMPLE_STEP * eps)
    step = lengths / (counts - 1)
    x, y, z = (origin[a] + step[a] * np.arange(counts[a]) for a in range(3))
    values = np.empty(counts[::-1])
    Y, X = np.meshgrid(y, x, indexing="ij")            # (ny, nx), x fastest
    slabs = max(1, 2 ** 18 // X.size)                  # about 2^18 points a call
    for k in range(0, len(z), slabs):
        zk = z[k:k + slabs]
        points = np.column_stack([np.tile(X.ravel(), len(zk)), np.tile(Y.ravel(), len(zk)),
                                  np.repeat(zk, X.size)])
        values[k:k + len(zk)] = field_h(points)[0].reshape(len(zk), *X.shape)
    return values, origin, step


def _sample_counts(lengths, step):
    """Points along each of `lengths` at spacings at most `step`, the step
    grown until they number at most SAMPLE_POINTS in all."""
    while True:
        counts = np.ceil(lengths / step - 1e-9).astype(np.int64) + 1
        total = int(np.prod(counts))
        if total <= SAMPLE_POINTS:
            return counts
        step *= max((total / SAMPLE_POINTS) ** (1.0 / 3.0), 1.0 + 1e-3)
