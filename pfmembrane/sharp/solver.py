"""Axisymmetric sharp-interface Canham-Helfrich shapes (reference energies).

Minimizes E = (k/2) int (H - C0)^2 dS over closed surfaces of revolution at
fixed area A0 = 4 pi R0^2 and volume V0 = v (4/3) pi R0^3, with H the mean
curvature (1/R on a sphere of radius R, outward normal; C0 > 0 favours
sphere-like curvature).

Method
------
The generating curve is parametrized by arc length s = l theta, theta in
[0, pi], from the pole at s = 0 to the pole at s = pi l, through its tangent
angle

    psi(theta) = theta + sum_k a_k sin(k theta),   r' = cos psi,  z' = sin psi.

Every sine mode keeps psi(0) = 0, psi(pi) = pi and the odd symmetry of psi
about both poles, so the surface is smooth at the poles and psi(theta),
r(theta), the curvatures psi_s and sin(psi)/r are analytic and 2 pi periodic:
the sine series converges exponentially. Up-down symmetric shapes use the
even modes only (then r(pi) = 0 holds by symmetry); the general path uses all
modes and imposes the closure r(pi) = 0 as a third constraint.

Integrals are spectral on the midpoint grid theta_j = pi (j + 1/2) / m with
m = 2 n nodes for the highest mode n: every integrand (r (H - C0)^2, r,
r^2 sin psi) is odd in theta about both poles and is integrated exactly as a
sine interpolant; r and z are spectral antiderivatives of cos psi and sin psi. Gradients are analytic, Hessians come
from complex-step differentiation of the gradients (exact to rounding).

The constrained minimum is found by a feasible-path Newton iteration: each
Newton-Lagrange (KKT) step is projected back onto the constraints, and a
Levenberg shift of the Hessian is raised until the energy decreases, so the
iteration descends to a minimum from rough starts and converges
quadratically near it. Branches are followed by continuation in (v, C0): from
a slightly deformed sphere (oblate/prolate) or from a smoothed
sphere-inside-sphere (stomatocyte, started at v = 0.5).

Accuracy: v = 0.8 oblate and prolate energies are converged to rounding
at n = 16 and agree with the literature values to 1e-7 and 2e-6 (table in
`solve` and runs/sharp/validation.md, written by
``python -m pfmembrane.sharp --table runs/sharp/validation.md``).

Range (C0 = 0): oblate (discocyte) shapes down to v ~ 0.505, where the two
dimples meet on the axis; prolate shapes down to small v (long cigars need
more modes). Stomatocytes are local minima from v ~ 0.25, where the inner
pole reaches the outer one, up to v ~ 0.66, where the branch ends; their
narrow neck needs many modes, and the default resolution gives about 1e-9
relative for 0.4 <= v <= 0.66 but only ~2e-6 at v = 0.3. A RuntimeWarning
reports an unresolved spectrum. Spontaneous curvature works on all
branches; C0 < 0 narrows the stomatocyte neck towards a closed-neck limit
shape (C0 R0 = -0.25 at v = 0.6 is resolved only to ~1e-5).

Lagrange multipliers follow L = E - tension (A - A0) - pressure (V - V0),
so tension = dE/dA0 and pressure = dE/dV0 along the branch (the tension is
the negative of the usual mechanical membrane tension).
"""
import argparse
import time
import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.optimize import brentq

BRANCHES = ('oblate', 'prolate', 'stomatocyte')
# Resolution for n=None: start at DEFAULT_N and double up to MAX_N until the
# top quarter of the sine spectrum is below TAIL.
DEFAULT_N = {'oblate': 32, 'prolate': 32, 'stomatocyte': 64}
MAX_N = {'oblate': 128, 'prolate': 128, 'stomatocyte': 256}
TAIL = 1e-6
LITERATURE = {'oblate': 9.12657, 'prolate': 8.71756}   # v = 0.8, k = 1, C0 = 0


@dataclass
class SharpShape:
    """A stationary shape of the Canham-Helfrich energy.

    Attributes
    ----------
    energy, area, volume : float
        E, A and V of the discrete shape.
    r, z : ndarray
        Generating curve from pole (r = 0) to pole (r = 0), 8 n + 1 points
        uniform in arc length (n the highest sine mode), z shifted so that
        the centroid of the enclosed volume is at z = 0.
    tension, pressure : float
        Multipliers of L = E - tension (A - A0) - pressure (V - V0), i.e.
        dE/dA0 and dE/dV0. At v = 1 (sphere) they are not unique; the limits
        v -> 1 of the oblate and prolate branches are reported.
    """
    energy: float
    area: float
    volume: float
    r: np.ndarray
    z: np.ndarray
    tension: float
    pressure: float


def _antiderivative_bases(theta, m):
    """int_0^theta of cos(j t) for 0 <= j < m and of sin(j t) for 1 <= j <= m."""
    t = np.asarray(theta)[:, None]
    j = np.arange(1, m + 1)
    cos_part = np.concatenate([t, np.sin(j[:-1] * t) / j[:-1]], axis=1)
    return cos_part, (1.0 - np.cos(j * t)) / j


class _Grid:
    """Sine modes, quadrature nodes and spectral integration for one resolution.

    Parameters
    ----------
    n : int
        Highest sine mode of psi.
    symmetric : bool
        Even modes only (up-down symmetric shapes, closure automatic).
    """

    def __init__(self, n, symmetric):
        self.n, self.symmetric = n, symmetric
        self.modes = np.arange(2, n + 1, 2) if symmetric else np.arange(1, n + 1)
        m = 2 * n      # twice the highest mode: resolves the quadratic products
        th = np.pi * (np.arange(m) + 0.5) / m
        self.theta = th
        self.S = np.sin(np.outer(th, self.modes))
        self.D = self.modes * np.cos(np.outer(th, self.modes))
        # Interpolation: even functions in cos(j theta), 0 <= j < m, odd ones
        # in sin(j theta), 1 <= j <= m; both are exact on the m nodes.
        j = np.arange(m)
        self.cos_coefficients = np.linalg.inv(np.cos(np.outer(th, j)))
        self.sin_coefficients = np.linalg.inv(np.sin(np.outer(th, j + 1)))
        self.P = _antiderivative_bases(th, m)[0] @ self.cos_coefficients
        self.w = _antiderivative_bases([np.pi], m)[1][0] @ self.sin_coefficients   # int_0^pi, odd
        self.w_even = np.full(m, np.pi / m)                                        # int_0^pi, even
        self.output = np.linspace(0.0, np.pi, 4 * m + 1)

    @property
    def n_constraints(self):
        return 2 if self.symmetric else 3

    def curve(self, x, theta):
        """psi, r, z at the points theta of [0, pi] for the variables x = (a, l)."""
        a, l = x[:-1], x[-1]
        psi_nodes = self.theta + self.S @ a
        cos_anti, sin_anti = _antiderivative_bases(theta, self.theta.size)
        return (theta + np.sin(np.outer(theta, self.modes)) @ a,
                l * (cos_anti @ (self.cos_coefficients @ np.cos(psi_nodes))),
                l * (sin_anti @ (self.sin_coefficients @ np.sin(psi_nodes))))

    def functionals(self, x, c0):
        """Values and gradients of (E, A, V[, r(pi)]) for k = 1.

        Parameters
        ----------
        x : ndarray, shape (b, nx)
            A batch of variables (a_k, l); may be complex (complex step).
        c0 : float
            Spontaneous curvature.

        Returns
        -------
        values : ndarray, shape (b, nf)
        gradients : ndarray, shape (b, nf, nx)
        """
        a, l = x[:, :-1], x[:, -1:]
        psi = self.theta + a @ self.S.T
        psi_t = 1.0 + a @ self.D.T
        cs, sn = np.cos(psi), np.sin(psi)
        r = l * (cs @ self.P.T)
        e = 0.5 * (psi_t / l + sn / r) - c0       # H - C0
        zero = np.zeros_like(r)
        pi = np.pi
        # Each functional is l int_0^pi f(r, psi, psi_theta, l) dtheta; with
        # the partial derivatives (f, f_r, f_psi, f_psi_theta, f_l) of f the
        # chain rule through r = l P cos(psi) gives all gradients alike.
        parts = (
            (pi * r * e * e, pi * e * (e - sn / r), pi * e * cs, pi * r * e / l, -pi * r * e * psi_t / l ** 2),
            (2 * pi * r, 2 * pi + zero, zero, zero, zero),
            (pi * r * r * sn, 2 * pi * r * sn, pi * r * r * cs, zero, zero),
        )
        w = self.w
        values, gradients = [], []
        for f, f_r, f_psi, f_t, f_l in parts:
            g_psi = l * w * f_psi - l * l * sn * ((w * f_r) @ self.P)
            g_a = g_psi @ self.S + (l * w * f_t) @ self.D
            g_l = (f + f_r * r + l * f_l) @ w
            values.append(l[:, 0] * (f @ w))
            gradients.append(np.concatenate([g_a, g_l[:, None]], axis=1))
        if not self.symmetric:
            closure = l[:, 0] * (cs @ self.w_even)
            values.append(closure)
            gradients.append(np.concatenate([(-l * self.w_even * sn) @ self.S,
                                             (closure / l[:, 0])[:, None]], axis=1))
        return np.stack(values, axis=1), np.stack(gradients, axis=1)

    def hessians(self, x, c0, h=1e-30):
        """Hessians of (E, A, V[, r(pi)]) at x, shape (nf, nx, nx), by complex step."""
        probe = x + 1j * h * np.eye(x.size)
        return np.moveaxis(self.functionals(probe, c0)[1].imag / h, 1, 0)


def _evaluate(grid, x, c0):
    values, gradients = grid.functionals(x[None], c0)
    return values[0], gradients[0]


def _project(grid, x, targets, c0, iterations=30):
    """Closest feasible point by Gauss-Newton; None if it fails or r <= 0 somewhere."""
    for _ in range(iterations):
        values, gradients = _evaluate(grid, x, c0)
        residual = values[1:] - targets
        if np.linalg.norm(residual) < 1e-13 * np.linalg.norm(targets):
            return x if np.min(grid.curve(x, grid.theta)[1]) > 0 else None
        x = x - np.linalg.lstsq(gradients[1:], residual, rcond=None)[0]
        if not np.all(np.isfinite(x)):
            return None
    return None


def _minimize(grid, x, targets, c0, tol=1e-10, max_iterations=100):
    """Feasible-path Newton-Lagrange minimization of E at fixed (A, V[, r(pi)]).

    Returns
    -------
    x : ndarray
        Variables of the minimum (feasible to 1e-13 relative).
    multipliers : ndarray
        (tension, pressure[, closure]) with grad E = sum multiplier * grad constraint.

    Raises
    ------
    RuntimeError
        If x cannot be made feasible or the iteration does not converge.
    """
    x = _project(grid, x, targets, c0)
    if x is None:
        raise RuntimeError('start not feasible')
    nc = targets.size
    shift = 0.0
    for _ in range(max_iterations):
        values, gradients = _evaluate(grid, x, c0)
        J = gradients[1:]
        multipliers = np.linalg.lstsq(J.T, gradients[0], rcond=None)[0]
        g = gradients[0] - multipliers @ J
        if np.linalg.norm(g) < tol * max(1.0, abs(values[0])):
            return x, multipliers
        H = grid.hessians(x, c0)
        HL = H[0] - np.tensordot(multipliers, H[1:], axes=1)
        scale = np.max(np.abs(np.diag(HL)))
        while True:
            K = np.block([[HL + shift * np.eye(x.size), -J.T], [J, np.zeros((nc, nc))]])
            step = np.linalg.solve(K, np.concatenate([-g, np.zeros(nc)]))[:x.size]
            trial = _project(grid, x + step, targets, c0)
            # The tolerance admits rounding once the iteration has converged.
            if trial is not None and _evaluate(grid, trial, c0)[0][0] <= values[0] + 1e-12 * abs(values[0]):
                x = trial
                shift = shift / 10 if shift > 1e-6 * scale else 0.0
                break
            if shift > 1e10 * scale:
                raise RuntimeError('no descent step')
            shift = max(10 * shift, 1e-4 * scale)
    raise RuntimeError('Newton iteration did not converge')


def _start(grid, branch, v):
    """Initial variables and their reduced volume for a branch (unit R0)."""
    x = np.zeros(grid.modes.size + 1)
    if branch == 'stomatocyte':
        # Outer sphere (Ro) with an inverted inner sphere (Ri) hanging from
        # its top pole, Ro^2 + Ri^2 = 1 and Ro^3 - Ri^3 = v = 0.5: psi rises
        # from 0 to pi, jumps by pi at the (smoothed) neck and falls back to pi.
        v = 0.5
        Ri = brentq(lambda Ri: (1 - Ri ** 2) ** 1.5 - Ri ** 3 - v, 0.0, np.sqrt(0.5))
        Ro = np.sqrt(1 - Ri ** 2)
        l = Ro + Ri
        s = grid.theta * l
        neck = 0.5 * (1 + np.tanh((grid.theta - np.pi * Ro / l) / 0.1))
        psi = (1 - neck) * s / Ro + neck * (2 * np.pi - (s - np.pi * Ro) / Ri)
        x[:-1] = np.linalg.lstsq(grid.S, psi - grid.theta, rcond=None)[0]
        x[-1] = l
        return x, v
    # The l = 2 deformation of the unit sphere, v ~ 1 - eps^2 / 2.
    v = max(v, 0.95)
    x[:-1][grid.modes == 2] = (-1 if branch == 'oblate' else 1) * np.sqrt(2 * (1 - v))
    x[-1] = 1.0
    return x, v


def _is_branch(grid, x, branch):
    """Whether x has the shape of the branch (rules out jumps to another branch)."""
    psi, r, z = grid.curve(x, grid.output)
    height, width = np.ptp(z), 2 * np.max(r)
    if branch == 'prolate':
        return height > width
    # Dimpled shapes must not pass through themselves on the axis.
    if z[-1] <= z[0]:
        return False
    if branch == 'oblate':
        return height < width
    # A stomatocyte is far from its mirror image psi(pi - theta) = pi - psi(theta).
    return np.max(np.abs(psi + psi[::-1] - np.pi)) > 0.1


def _settle(grid, x, branch, v, c0):
    """Minimum near x at (v, c0) that still belongs to the branch; unit R0 and k."""
    targets = np.array([4 * np.pi, v * 4 * np.pi / 3, 0.0][:grid.n_constraints])
    x, multipliers = _minimize(grid, x, targets, c0)
    if not _is_branch(grid, x, branch):
        raise RuntimeError(f'left the {branch} branch at v = {v:.4g}, C0 R0 = {c0:.4g}')
    return x, multipliers


def _follow(grid, branch, v, c0):
    """Continuation in (v, C0) from the start of the branch to (v, c0).

    Steps are at most 0.05 in v and 0.25 in C0 R0, halved on failure.
    """
    x, v_start = _start(grid, branch, v)
    x, multipliers = _settle(grid, x, branch, v_start, 0.0)
    t, dt = 0.0, 1.0 / max(1, int(np.ceil(max(abs(v - v_start) / 0.05, abs(c0) / 0.25))))
    while t < 1.0:
        t_next = min(1.0, t + dt)
        try:
            x, multipliers = _settle(grid, x, branch, v_start + t_next * (v - v_start), t_next * c0)
            t = t_next
        except RuntimeError:
            dt /= 2
            if dt < 1e-2:
                raise
    return x, multipliers


def _tail(grid, x):
    """Largest sine coefficient among the top quarter of the modes."""
    return np.max(np.abs(x[:-1][grid.modes > 0.75 * grid.n]))


def _refined(grid, x):
    """Grid with twice the modes and x on it (the new modes start at zero)."""
    finer = _Grid(2 * grid.n, grid.symmetric)
    y = np.zeros(finer.modes.size + 1)
    y[:-1][np.isin(finer.modes, grid.modes)] = x[:-1]
    y[-1] = x[-1]
    return finer, y


def _sphere_multipliers(c):
    """v -> 1 limits of (tension, pressure) for unit R0 and k, c = C0 R0.

    The l = 0 variation gives 2 tension + pressure = -c (1 - c); the oblate and
    prolate branches leave the sphere along the l = 2 mode, which is neutral
    when 4 tension + pressure = 3 - 3 c + 2 c^2.
    """
    return (3 - 2 * c + c * c) / 2, c - 3


def solve(reduced_volume, branch='oblate', c0=0.0, radius=1.0, k=1.0, n=None, *, symmetric=None):
    """Minimal-energy axisymmetric shape on one branch.

    Spectral tangent-angle discretization with a feasible-path Newton-Lagrange
    minimization and continuation from the sphere (see the module docstring).
    Convergence at v = 0.8, k = 1, C0 = 0 (relative error against n = 64;
    literature: 9.12657 oblate, 8.71756 prolate), each solve < 0.1 s:

    ====  ==============  =======  ==============  =======
      n   oblate E        error    prolate E       error
    ====  ==============  =======  ==============  =======
      4   9.131019726456  4.9e-04  8.709057800188  9.7e-04
      6   9.126600000327  3.4e-06  8.717490620771  6.3e-06
      8   9.126569519338  1.6e-08  8.717546343708  1.2e-07
     12   9.126569369109  1.1e-13  8.717545341777  2.4e-10
     16   9.126569369108  1.0e-15  8.717545339723  5.8e-13
     32   9.126569369108  2.6e-15  8.717545339718  < 1e-15
    ====  ==============  =======  ==============  =======

    The converged energies differ from the literature values by 6.9e-8
    (oblate) and 1.7e-6 (prolate) relative.

    Parameters
    ----------
    reduced_volume : float
        v in (0, 1]; v = 1 returns the sphere on every branch.
    branch : {'oblate', 'prolate', 'stomatocyte'}
    c0 : float
        Spontaneous curvature, in the inverse length unit of `radius` (the
        energy depends on c0 * radius only).
    radius : float
        R0, the radius of the sphere of the same area.
    k : float
        Bending rigidity.
    n : int, optional
        Highest sine mode. By default n starts at 32 (oblate, prolate) or 64
        (stomatocyte) and doubles, up to 128 or 256, until the top quarter
        of the sine spectrum is below 1e-6.
    symmetric : bool, optional
        Restrict to up-down symmetric shapes (even modes). Default: True for
        oblate/prolate, False (the general path) for the stomatocyte.

    Returns
    -------
    SharpShape

    Raises
    ------
    ValueError
        Unknown branch, v outside (0, 1], n < 2 or a symmetric stomatocyte.
    RuntimeError
        If the continuation loses the branch (e.g. stomatocyte at v > 0.66,
        oblate at v < 0.5).

    Warns
    -----
    RuntimeWarning
        If the sine spectrum is not resolved at the final n.
    """
    if branch not in BRANCHES:
        raise ValueError(f'unknown branch {branch!r}; expected one of {BRANCHES}')
    if not 0.0 < reduced_volume <= 1.0:
        raise ValueError(f'reduced volume must be in (0, 1], got {reduced_volume}')
    if symmetric is None:
        symmetric = branch != 'stomatocyte'
    if symmetric and branch == 'stomatocyte':
        raise ValueError('stomatocytes are not up-down symmetric')
    if n is not None and n < 2:
        raise ValueError(f'n must be at least 2, got {n}')
    adaptive = n is None
    grid = _Grid(DEFAULT_N[branch] if adaptive else n, symmetric)
    c = c0 * radius
    if reduced_volume == 1.0:
        x = np.zeros(grid.modes.size + 1)
        x[-1] = 1.0
        multipliers = _sphere_multipliers(c)
    else:
        x, multipliers = _follow(grid, branch, reduced_volume, c)
        while adaptive and _tail(grid, x) > TAIL and grid.n < MAX_N[branch]:
            grid, x = _refined(grid, x)
            x, multipliers = _settle(grid, x, branch, reduced_volume, c)
        if _tail(grid, x) > TAIL:
            warnings.warn(f'{branch} at v = {reduced_volume}, C0 R0 = {c}: sine spectrum not resolved '
                          f'(top modes up to {_tail(grid, x):.1e}) at n = {grid.n}',
                          RuntimeWarning, stacklevel=2)
    values = _evaluate(grid, x, c)[0]
    psi, r, z = grid.curve(x, grid.theta)
    centroid = x[-1] * (grid.w @ (np.pi * r * r * z * np.sin(psi))) / values[2]
    _, r, z = grid.curve(x, grid.output)
    r[[0, -1]] = 0.0      # r(pi) = 0 holds to rounding
    return SharpShape(energy=k * values[0], area=radius ** 2 * values[1], volume=radius ** 3 * values[2],
                      r=radius * r, z=radius * (z - centroid),
                      tension=k * multipliers[0] / radius ** 2, pressure=k * multipliers[1] / radius ** 3)


@lru_cache(maxsize=None)
def energy_reference(reduced_volume, branch, c0=0.0, radius=1.0, k=1.0):
    """Energy of `solve` at the default resolution, cached per argument tuple."""
    return solve(reduced_volume, branch, c0=c0, radius=radius, k=k).energy


def _embedded_prolate(reduced_volume, c, n):
    """The symmetric prolate of `solve` (unit R0, C0 R0 = c, n modes) on the grid of all
    modes: (that grid, its variables)."""
    half = _Grid(n, True)
    x_half, _ = _follow(half, 'prolate', reduced_volume, c)
    grid = _Grid(n, False)
    x = np.zeros(grid.modes.size + 1)
    x[:-1][grid.modes % 2 == 0], x[-1] = x_half[:-1], x_half[-1]
    return grid, x


def pear_mode(reduced_volume, c0=0.0, radius=1.0, n=32):
    """Least eigenvalue of the up-down antisymmetric second variation of the
    symmetric prolate at (v, C0): the Hessian of the Lagrangian on the tangent
    space of area, volume and closure, in the variables (a_1 ... a_n, l) of unit
    R0 and k, over the eigenvectors that lie mostly in the odd modes. Its sign
    change is the pear bifurcation of the prolate (SBL's D_pe); its scale depends
    on the coordinates, its zero does not. Returns (eigenvalue, unit eigenvector)."""
    from scipy.linalg import null_space
    c = c0 * radius
    grid, x = _embedded_prolate(reduced_volume, c, n)
    _, gradients = _evaluate(grid, x, c)
    J = gradients[1:]
    multipliers = np.linalg.lstsq(J.T, gradients[0], rcond=None)[0]
    H = grid.hessians(x, c)
    Z = null_space(J)
    values, vectors = np.linalg.eigh(Z.T @ (H[0] - np.tensordot(multipliers, H[1:], axes=1)) @ Z)
    vectors = Z @ vectors
    odd = np.append(grid.modes % 2 == 1, False)
    anti = np.flatnonzero((vectors[odd] ** 2).sum(axis=0) > 0.5)
    return values[anti[0]], vectors[:, anti[0]]


def pear_bifurcation(reduced_volume, bracket, radius=1.0, n=32):
    """C0 of the pear bifurcation of the symmetric prolate at v: the zero of
    `pear_mode` in C0 within `bracket` (raises ValueError without a sign change)."""
    return brentq(lambda c0: pear_mode(reduced_volume, c0, radius, n)[0], *bracket, xtol=1e-10)


# The sine modes of `shape_energy`: from SHAPE_MODES (the v = 0.8 shapes need 12-16), doubled
# until two fits agree to SHAPE_MODES_TOL, at most SHAPE_MODES_MAX and a quarter of the
# samples. A narrow neck needs more: on the sharp stomatocyte at v 0.6, c0 -0.5 (neck 0.025),
# 48 modes miss its energy by more than 1% (tests/test_levelset_energy.py).
SHAPE_MODES = 48
SHAPE_MODES_TOL = 1e-5
SHAPE_MODES_MAX = 512


def shape_energy(theta, psi, length, area, volume, c0=0.0, k=1.0, n=None):
    """Energy of a given generating curve, put on the constraints.

    The tangent angle psi(theta) of a closed curve (theta = pi s / length,
    s the arc length from pole to pole) is fitted by the sine series of
    `solve` (least squares, modes 1 ... n), and the series is moved by the
    smallest Gauss-Newton correction onto area, volume and closure.  As the
    minimum of `solve` is stationary on that constraint set, a curve a
    distance d from it gives the minimal energy up to O(d^2) (the energy of
    the uncorrected curve errs by O(d), through the constraint residuals).

    Parameters
    ----------
    theta, psi : ndarray, shape (M,)
        Samples of the tangent angle, psi = 0 at the first pole and pi at
        the second, counterclockwise in the (r, z) half-plane.
    length : float
        Length of the generating curve.
    area, volume : float
        Constraint values, in the units of `length`.
    c0 : float
        Spontaneous curvature, in the inverse units of `length`.
    k : float
        Bending rigidity.
    n : int, optional
        Highest sine mode; by default SHAPE_MODES, doubled until two fits
        agree to SHAPE_MODES_TOL (at most SHAPE_MODES_MAX and a quarter of
        the samples).

    Returns
    -------
    energy : float
        Energy of the corrected curve; NaN if no feasible correction is
        found near the curve.
    energy_curve : float
        Energy of the fitted curve itself.
    """
    if n is not None:
        return _shape_energy(theta, psi, length, area, volume, c0, k, n)
    n = SHAPE_MODES
    energies = _shape_energy(theta, psi, length, area, volume, c0, k, n)
    while 2 * n <= min(SHAPE_MODES_MAX, len(theta) // 4):
        n *= 2
        finer = _shape_energy(theta, psi, length, area, volume, c0, k, n)
        converged = np.allclose(finer, energies, rtol=SHAPE_MODES_TOL, atol=0.0, equal_nan=True)
        energies = finer
        if converged:
            break
    return energies


def _shape_energy(theta, psi, length, area, volume, c0, k, n):
    """`shape_energy` with n sine modes."""
    grid = _Grid(n, False)
    coefficients = np.linalg.lstsq(np.sin(np.outer(theta, grid.modes)), psi - theta,
                                   rcond=None)[0]
    x = np.append(coefficients, length / np.pi)
    energy_curve = k * _evaluate(grid, x, c0)[0][0]
    feasible = _project(grid, x, np.array([area, volume, 0.0]), c0)
    energy = np.nan if feasible is None else k * _evaluate(grid, feasible, c0)[0][0]
    return energy, energy_curve


def _timed(*args, **kwargs):
    """solve(*args, **kwargs) and its wall time, without the resolution warning
    (the tables show the convergence in n themselves)."""
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        shape = solve(*args, **kwargs)
    return shape, time.perf_counter() - start


def _tables():
    """Markdown lines of the validation tables (about a minute to compute)."""
    R0 = 0.4
    out = ['# Sharp-interface Canham-Helfrich shapes: validation', '',
           'Generated by `python -m pfmembrane.sharp --table runs/sharp/validation.md`;',
           'method in the docstring of `pfmembrane/sharp/solver.py`. k = 1, C0 = 0, R0 = 0.4',
           'unless stated; n = highest sine mode of the tangent angle, 2n quadrature',
           'nodes; times are wall-clock seconds of one `solve` (continuation included).', '']

    sphere = solve(1.0, radius=R0)
    out += ['## Sphere (v = 1)', '',
            f'E = {sphere.energy:.15f}, 2 pi = {2 * np.pi:.15f}, '
            f'relative error {abs(sphere.energy / (2 * np.pi) - 1):.1e}.', '']

    out += ['## v = 0.8, up-down symmetric path (even modes up to n)', '',
            '| n | unknowns | oblate E | vs 9.12657 | vs n = 64 | s | prolate E | vs 8.71756 | vs n = 64 | s |',
            '|---|---|---|---|---|---|---|---|---|---|']
    best = {b: solve(0.8, b, radius=R0, n=64).energy for b in LITERATURE}
    for n in (4, 6, 8, 10, 12, 16, 24, 32, 48):
        row = f'| {n}{" (default)" if n == DEFAULT_N["oblate"] else ""} | {n // 2 + 1} |'
        for branch, literature in LITERATURE.items():
            shape, seconds = _timed(0.8, branch, radius=R0, n=n)
            row += (f' {shape.energy:.12f} | {abs(shape.energy / literature - 1):.1e} |'
                    f' {abs(shape.energy / best[branch] - 1):.1e} | {seconds:.2f} |')
        out.append(row)
    out += ['', 'Reference (n = 64): ' + ', '.join(f'{b} {e:.13f}' for b, e in best.items()) + '.', '']

    out += ['## v = 0.8, general path (all modes up to n, closure constraint)', '',
            '| n | oblate E | vs symmetric n = 64 | s | prolate E | vs symmetric n = 64 | s |',
            '|---|---|---|---|---|---|---|']
    for n in (8, 16, 32):
        row = f'| {n} |'
        for branch in LITERATURE:
            shape, seconds = _timed(0.8, branch, radius=R0, n=n, symmetric=False)
            row += f' {shape.energy:.12f} | {abs(shape.energy / best[branch] - 1):.1e} | {seconds:.2f} |'
        out.append(row)

    out += ['', '## Lagrange multipliers (v = 0.8, R0 = 0.4)', '',
            'L = E - tension (A - A0) - pressure (V - V0). Checks: scale invariance at',
            'C0 = 0 gives 2 A tension + 3 V pressure = 0; dE/dv (central difference,',
            'h = 1e-4) equals pressure dV0/dv = pressure (4/3) pi R0^3.', '',
            '| branch | tension | pressure | 2A tension + 3V pressure | dE/dv | pressure dV0/dv |',
            '|---|---|---|---|---|---|']
    for branch in LITERATURE:
        shape = solve(0.8, branch, radius=R0)
        slope = (solve(0.8 + 1e-4, branch, radius=R0).energy
                 - solve(0.8 - 1e-4, branch, radius=R0).energy) / 2e-4
        out.append(f'| {branch} | {shape.tension:.10f} | {shape.pressure:.10f} |'
                   f' {2 * shape.area * shape.tension + 3 * shape.volume * shape.pressure:.1e} |'
                   f' {slope:.8f} | {shape.pressure * 4 * np.pi * R0 ** 3 / 3:.8f} |')
    tension, pressure = _sphere_multipliers(0.0)
    near = [solve(0.9999, b) for b in LITERATURE]
    out += ['', f'Sphere limit (R0 = 1): tension {tension}, pressure {pressure}; at v = 0.9999 '
            + ', '.join(f'{b} ({s.tension:.4f}, {s.pressure:.4f})' for b, s in zip(LITERATURE, near)) + '.', '']

    out += ['## Stomatocytes, C0 = 0 (general path)', '',
            'Fixed n and the default (n doubled from 64 up to 256 until the top quarter',
            'of the spectrum is below 1e-6); oblate and prolate energies (default n) for',
            'comparison: the oblate-stomatocyte crossing is the discontinuous transition',
            'near v = 0.59 of Seifert, Berndl and Lipowsky (1991).', '',
            '| v | n = 64 | n = 128 | n = 192 | default | its n | s | oblate | prolate |',
            '|---|---|---|---|---|---|---|---|---|']
    for v in (0.4, 0.5, 0.55, 0.6, 0.65):
        row = f'| {v} |' + ''.join(f' {_timed(v, "stomatocyte", radius=R0, n=n)[0].energy:.10f} |'
                                   for n in (64, 128, 192))
        shape, seconds = _timed(v, 'stomatocyte', radius=R0)
        row += f' {shape.energy:.10f} | {(shape.r.size - 1) // 8} | {seconds:.1f} |'
        for branch in LITERATURE:
            try:
                row += f' {_timed(v, branch, radius=R0)[0].energy:.10f} |'
            except RuntimeError:
                row += ' (dimples meet) |'
        out.append(row)
    try:
        solve(0.67, 'stomatocyte', radius=R0)
        end = 'The branch continues beyond v = 0.67.'
    except RuntimeError as error:
        end = f'Asked for v = 0.67: "{error}" (the branch ends).'
    out += ['', end, '']

    out += ['## Spontaneous curvature (C0 in units of 1/R0)', '',
            'v = 0.8, oblate and prolate:', '',
            '| C0 R0 | oblate n = 16 | oblate n = 32 | prolate n = 16 | prolate n = 32 |',
            '|---|---|---|---|---|']
    for c in (-1.0, -0.5, 0.5, 1.0):
        out.append(f'| {c} |' + ''.join(f' {_timed(0.8, b, c0=c / R0, radius=R0, n=n)[0].energy:.12f} |'
                                         for b in LITERATURE for n in (16, 32)))
    out += ['', 'Stomatocyte, v = 0.6: C0 < 0 narrows the neck towards the closed-neck',
            'limit shape, which the sine series resolves only slowly.', '',
            '| C0 R0 | n = 64 | n = 128 | n = 192 | default | its n |', '|---|---|---|---|---|---|']
    for c in (-0.1, -0.25):
        shape = _timed(0.6, 'stomatocyte', c0=c / R0, radius=R0)[0]
        out.append(f'| {c} |' + ''.join(f' {_timed(0.6, "stomatocyte", c0=c / R0, radius=R0, n=n)[0].energy:.10f} |'
                                         for n in (64, 128, 192))
                   + f' {shape.energy:.10f} | {(shape.r.size - 1) // 8} |')
    return out


def main(argv=None):
    """Write the validation tables (markdown) to the file given by --table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--table', required=True, help='output markdown file')
    args = parser.parse_args(argv)
    lines = _tables()
    with open(args.table, 'w') as f:
        f.write('\n'.join(lines) + '\n')


if __name__ == '__main__':
    main()
