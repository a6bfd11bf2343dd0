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

import numpy as np
from scipy.interpolate import RectBivariateSpline

from pfmembrane.analysis import surface
from pfmembrane.kernels.basis import folded_basis
from pfmembrane.kernels.maxent import interpolate

RASTER = 1.0 / 6      # raster step, in eps
MARCH = 0.5           # marching-tetrahedra step, in eps
R_AXIS = 1e-9         # 1/r terms are taken at r >= R_AXIS (their limits are finite)


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

    @classmethod
    def of(cls, nodes, phi, m, sine, box, eps, beta, cutoff, plane=None):
        step = RASTER * eps
        r = np.arange(0.0, box[0] + step / 2, step)
        z0 = plane if plane is not None else 0.0
        z = np.arange(z0, box[1] + step / 2, step)
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
        return cls(splines, np.asarray(m), np.asarray(sine, bool), 0.5 * box[1], plane)

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
    """(phi, grad, hess) at points, each computed when first asked for
    (the level set's sampling needs phi alone)."""

    def __init__(self, field, points):
        self.f, self.points = field, points
        self._parts = None

    def __getitem__(self, i):
        if i == 0 and self._parts is None:
            return self._phi()
        if self._parts is None:
            self._parts = self._all()
        return self._parts[i]

    def _phi(self):
        f = self.f
        r, theta, z, _ = f.cylindrical(self.points)
        out = np.zeros(len(r))
        for s, m, sine in zip(f.splines, f.m, f.sine):
            T = np.sin(m * theta) if sine else np.cos(m * theta)
            out += r ** m * s.ev(r, z) * T
        return out

    def _all(self):
        """phi, its Cartesian gradient and Hessian from the cylindrical
        derivatives f_r, f_theta, f_z, f_rr, f_rtheta, f_thetatheta, f_rz,
        f_thetaz, f_zz of sum_j g_j(r, z) T_j(theta), g_j = r^m S_j."""
        f = self.f
        r, theta, z, flip = f.cylindrical(self.points)
        r = np.maximum(r, R_AXIS)
        n = len(r)
        F = {k: np.zeros(n) for k in ('', 'r', 't', 'z', 'rr', 'rt', 'tt', 'rz', 'tz', 'zz')}
        for s, m, sine in zip(f.splines, f.m, f.sine):
            S, Sr, Sz = s.ev(r, z), s.ev(r, z, dx=1), s.ev(r, z, dy=1)
            Srr, Srz, Szz = s.ev(r, z, dx=2), s.ev(r, z, dx=1, dy=1), s.ev(r, z, dy=2)
            rm = r ** m
            rm1 = m * r ** (m - 1.0) if m else np.zeros(n)
            rm2 = m * (m - 1.0) * r ** (m - 2.0) if m > 1 else np.zeros(n)
            g, gr, gz = rm * S, rm1 * S + rm * Sr, rm * Sz
            grr, grz, gzz = rm2 * S + 2 * rm1 * Sr + rm * Srr, rm1 * Sz + rm * Srz, rm * Szz
            c, sn = np.cos(m * theta), np.sin(m * theta)
            T, dT, d2T = (sn, m * c, -m * m * sn) if sine else (c, -m * sn, -m * m * c)
            for key, a, b in (('', g, T), ('r', gr, T), ('t', g, dT), ('z', gz, T),
                              ('rr', grr, T), ('rt', gr, dT), ('tt', g, d2T),
                              ('rz', grz, T), ('tz', gz, dT), ('zz', gzz, T)):
                F[key] += a * b
        c, s = np.cos(theta), np.sin(theta)
        fr, ft, fz = F['r'], F['t'] / r, F['z'] * flip
        grad = np.column_stack([c * fr - s * ft, s * fr + c * ft, fz])
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
    (MARCH eps by default), shifted off the axis by an irrational fraction so
    that no sample lies on it."""
    step = step or MARCH * eps
    shift = step * (np.sqrt(2) - 1) / 3
    Rb, Zb = box
    lower = np.array([-Rb + shift, -Rb + shift, 0.0 + shift])
    upper = np.array([Rb, Rb, Zb])
    return surface.measure(field, lower, upper, step, k=k, c0=c0)
