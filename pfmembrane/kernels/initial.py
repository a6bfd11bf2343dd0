"""Initial guesses: spheroids with the scene's area and volume, tanh profile."""
import numpy as np
from scipy.optimize import brentq


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
    v = volume / (4.0 / 3.0 * np.pi * R ** 3)
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
