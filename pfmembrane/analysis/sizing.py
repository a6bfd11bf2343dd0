"""Boxes sized from the vesicle: the extents of a scene's shapes plus a margin.

The phase field decays from the membrane like the profile tanh(d / (sqrt2 eps)):
1 + phi ~ 2 exp(-sqrt2 d / eps), so a margin of AUTO_MARGIN = 7 eps leaves
phi within 1e-4 of its boundary value -1 at the box edges.
"""
import math
import warnings

import numpy as np

from pfmembrane.sharp import solver as sharp
from pfmembrane.io.options import STARTS, STARTS_3D, UsageError, targets
from pfmembrane.kernels.initial import construction, extent
from pfmembrane.kernels.functionals import F_E
from pfmembrane.kernels.nodes import nodal_spacing, uniform
from pfmembrane.paper import PAPER_BOX

AUTO_MARGIN = 7.0
AUTO_STEP = 0.01  # an automatic box is rounded up to a multiple of this
BOX_STEP = 0.1    # a study's box that must outgrow the paper's grows to a multiple of this


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
    area, volume = targets(radius, v)
    sizes = {kind: extent(kind, construction(kind, branch, area, volume))
             for kind in STARTS[branch] if kind not in ('sharp', *STARTS_3D)}
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
    if not sizes:  # the branch's only start is the sharp shape, and that solver lost it
        raise UsageError(f"-pf_box auto: no {branch} at v {', '.join(format(v, 'g') for v in vs)}"
                         f", c0 {c0:g}: the sharp-interface solver does not reach that branch "
                         f"there, the {branch}'s only start")
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


def default_box(required):
    """A studies' box holding `required` (Rb, Zb): the paper's box, each side grown
    to a multiple of `BOX_STEP` where `required` exceeds it, so that the scenes the
    paper's box holds share the grids of Tables 1, 2. Not collective."""
    return tuple(p if q <= p else math.ceil(q / BOX_STEP - 1e-9) * BOX_STEP
                 for p, q in zip(PAPER_BOX, required))


def uniform_grid(box, nodes):
    """(node count, mean nodal spacing) of the near-uniform grid of about `nodes`
    nodes of the full `box`: the nodes `pf.Grid.uniform` builds, without their basis
    (the spacing: the mean distance to the Delaunay neighbours, the axis mirrored).
    Not collective."""
    grid = uniform(box, nodes)
    return len(grid), float(np.mean(nodal_spacing(grid)))


def branch_box(branch, vs, eps, radius, c0=0.0, margin=5.0, step=0.05):
    """One box for a branch followed over the volumes `vs`: the largest `required_box`
    (`margin` eps) of its shapes at those of `vs` where the sharp solver finds one,
    each side rounded up to a multiple of `step`. Raises RuntimeError where it finds
    none. Not collective; deterministic."""
    need = np.zeros(2)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        for v in vs:
            try:
                need = np.maximum(need, required_box(branch, [v], eps, radius, c0,
                                                     margin=margin)[0])
            except (RuntimeError, ValueError):
                continue
    if not need.any():
        raise RuntimeError(f"no sharp {branch} shape at C0 = {c0:g} sizes a box")
    return rounded_up(need, step)


def bulk_offset(nu_volume, eps):
    """The leading-order offset delta of phi from -1 in the bulk, away from the vesicle:
    delta = nu_V eps^3 / (8 f_E), f_E = 3 / (8 sqrt2) the bending functional's constant
    (the Euler-Lagrange equation in the bulk, where the bending term dominates). The
    volume (|Omega| + int phi) / 2 counts delta |Omega| / 2 of the bulk as vesicle, so at
    finite eps a box changes the vesicle and its energy. Not collective."""
    return nu_volume * eps ** 3 / (8 * F_E)
