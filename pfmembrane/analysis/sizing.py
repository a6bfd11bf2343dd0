"""Boxes sized from the vesicle: the extents of a scene's shapes plus a margin.

The phase field decays from the membrane like the profile tanh(d / (sqrt2 eps)):
1 + phi ~ 2 exp(-sqrt2 d / eps), so a margin of AUTO_MARGIN = 7 eps leaves
phi within 1e-4 of its boundary value -1 at the box edges.
"""
import math

import numpy as np

from pfmembrane.sharp import solver as sharp
from pfmembrane.io.options import STARTS
from pfmembrane.kernels.initial import construction, extent

AUTO_MARGIN = 7.0
AUTO_STEP = 0.01  # an automatic box is rounded up to a multiple of this


def extents(branch, v, radius, c0=0.0, k=1.0):
    """Half-sizes of the shapes of a branch at reduced volume v.

    Not collective.

    Returns
    -------
    dict
        ``sharp``: (max r, max |z - z_centroid|) of the sharp-interface shape
        (`pfmembrane.sharp.solve`), absent where that solver loses the branch;
        and for each constructed start of the branch (``spheroid``, ``torus``,
        ``spheres``: `kernels.initial.construction`), its half-sizes.
    """
    area, volume = 4.0 * math.pi * radius ** 2, v * 4.0 / 3.0 * math.pi * radius ** 3
    sizes = {kind: extent(kind, construction(kind, branch, area, volume))
             for kind in STARTS[branch] if kind != 'sharp'}
    if branch not in sharp.BRANCHES:
        return sizes
    try:
        shape = sharp.solve(v, branch, c0=c0, radius=radius, k=k)
    except RuntimeError:  # the sharp solver lost the branch: the constructed start alone
        return sizes
    sizes['sharp'] = extent('sharp', (shape.r, shape.z))
    return sizes


def required_box(branch, vs, eps, radius, c0=0.0, k=1.0, margin=AUTO_MARGIN):
    """Smallest (Rb, Zb) holding every shape of the branch at the volumes `vs`.

    Not collective.  The vesicle is centred at Zb / 2 (moment constraint); each
    of its sharp-interface shape and constructed starts needs `margin` eps to
    r = Rb and to z = 0, Zb.

    Returns
    -------
    box : tuple of float
        (Rb, Zb) needed.
    sizes : dict
        ``sharp`` and the constructed starts' kinds (`extents`): the largest
        half-sizes (r, z) over `vs`.
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
    return rounded_up(need, AUTO_STEP)


def rounded_up(box, step):
    """Each side of `box` rounded up to a multiple of `step` (an exact multiple kept)."""
    return tuple(round(math.ceil(side / step - 1e-9) * step, 10) for side in box)
