"""The max-ent basis of a node set at given points: its locality beta_a and,
on a half box, the mirror images of the nodes folded onto the nodes themselves."""
import numpy as np

from pfmembrane.kernels import maxent, nodes as nodesets
from pfmembrane.kernels.nodes import nodal_spacings


def spacing_and_locality(nodes, gamma, smoothing, plane=None, floor=0.0):
    """The raw nodal spacing h_a and the locality beta_a = gamma / s_a^2, s_a
    the smoothed h_a (`nodes.nodal_spacing`) or, with a `floor` Q in (0, 1),
    max(s_a, s_Q), s_Q the Q-quantile of s_a.

    The floor gives the finest nodes of a graded (adapted) set one locality,
    so that the approximant's variance does not follow the spacing across
    the band the interfaces sweep (runs/atlas/notes.md, "One locality over
    the interfaces' band")."""
    h, s = nodal_spacings(nodes, smoothing, plane)
    if floor > 0.0:
        s = np.maximum(s, np.quantile(s, floor))
    return h, gamma / s ** 2


def locality(nodes, gamma, smoothing, plane=None, floor=0.0):
    """beta_a of `spacing_and_locality`."""
    return spacing_and_locality(nodes, gamma, smoothing, plane, floor)[1]


def folded_basis(points, nodes, beta, cutoff, derivatives, plane=None):
    """Max-ent basis at `points` whose columns are the nodes themselves.

    Not collective. Mirrors (see `nodes.with_mirrors`) enter the sums and
    each appears under its original's index, so a row may list a node
    several times; sparse products and `maxent.interpolate` add them.
    """
    radius = maxent.support_radius(beta, cutoff)
    aug, beta_aug, owner = nodesets.with_mirrors(nodes, beta, radius, plane)
    basis = maxent.local_maxent(points, aug, beta_aug, cutoff, derivatives=derivatives)
    return basis._replace(indices=owner[basis.indices])
