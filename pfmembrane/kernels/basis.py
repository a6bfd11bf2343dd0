"""The max-ent basis of a node set at given points: its locality beta_a and,
on a half box, the mirror images of the nodes folded onto the nodes themselves."""
from pfmembrane.kernels import maxent, nodes as nodesets
from pfmembrane.kernels.nodes import nodal_spacing


def locality(nodes, gamma, smoothing, plane=None):
    """beta_a = gamma / h_a^2 with the smoothed nodal spacing (`nodes.nodal_spacing`)."""
    return gamma / nodal_spacing(nodes, smoothing=smoothing, plane=plane) ** 2


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
