"""Boxes sized from the vesicle: the extents of a scene's shapes plus a margin.

The phase field decays from the membrane like the profile tanh(d / (sqrt2 eps)):
1 + phi ~ 2 exp(-sqrt2 d / eps), so a margin of AUTO_MARGIN = 7 eps leaves
phi within 1e-4 of its boundary value -1 at the box edges.
"""
import math

import numpy as np

from pfmembrane.analysis import sharp
from pfmembrane.kernels.initial import spheroid_axes

AUTO_MARGIN = 7.0
AUTO_STEP = 0.01  # an automatic box is rounded up to a multiple of this


def extents(branch, v, radius, c0=0.0, k=1.0):
    """Half-sizes of the shapes of a branch at reduced volume v.

    Not collective.

    Returns
    -------
    dict
        ``sharp``: (max r, max |z - z_centroid|) of the sharp-interface shape
        (`pfmembrane.analysis.sharp.solve`), absent where that solver loses the branch;
        ``spheroid``: semi-axes (a, c) of the initial spheroid a fresh run
        starts from.
    """
    area, volume = 4.0 * math.pi * radius ** 2, v * 4.0 / 3.0 * math.pi * radius ** 3
    sizes = {'spheroid': spheroid_axes(area, volume, branch)}
    try:
        shape = sharp.solve(v, branch, c0=c0, radius=radius, k=k)
    except RuntimeError:  # the sharp solver lost the branch: the spheroid alone
        return sizes
    sizes['sharp'] = (float(np.max(shape.r)), float(np.max(np.abs(shape.z))))
    return sizes


def required_box(branch, vs, eps, radius, c0=0.0, k=1.0, margin=AUTO_MARGIN):
    """Smallest (Rb, Zb) holding every shape of the branch at the volumes `vs`.

    Not collective.  The vesicle is centred at Zb / 2 (moment constraint); each
    of its sharp-interface shape and initial spheroid needs `margin` eps to
    r = Rb and to z = 0, Zb.

    Returns
    -------
    box : tuple of float
        (Rb, Zb) needed.
    sizes : dict
        ``sharp`` and ``spheroid``: the largest half-sizes (r, z) over `vs`.
    """
    sizes = {}
    for v in vs:
        for kind, size in extents(branch, v, radius, c0, k).items():
            sizes[kind] = tuple(np.maximum(sizes.get(kind, (0.0, 0.0)), size))
    r, z = np.max(list(sizes.values()), axis=0) + margin * eps
    return (float(r), float(2.0 * z)), sizes


def auto_box(branch, v, eps, radius, c0=0.0, k=1.0):
    """The box of `-pf_box auto`: `required_box` with AUTO_MARGIN eps, each
    side rounded up to a multiple of AUTO_STEP. Not collective; deterministic,
    so every rank finds the same box."""
    need, _ = required_box(branch, [v], eps, radius, c0, k)
    return tuple(round(math.ceil(side / AUTO_STEP - 1e-9) * AUTO_STEP, 10) for side in need)
