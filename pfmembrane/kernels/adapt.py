"""Node adaptivity (paper Section 4.2, Appendix B): CVT relocation of the nodes
for rho = 1 + f |grad phi_h| of a solved field, and transfer of phi_h to them.
With a band w, |grad phi_h| is first replaced by its largest value within w,
so the density is flat across the interface and the nodes grade only where
phi_h is near +-1.

The density is tabulated once on a raster finer than the old grid's smallest
spacing, then interpolated bilinearly by every CVT step. Pure numpy/scipy:
`parallel.adapt` shares the raster among the ranks and runs the relocation
on one.
"""
import numpy as np
from scipy.ndimage import map_coordinates, maximum_filter

from pfmembrane.kernels import cvt, maxent
from pfmembrane.kernels.basis import folded_basis
from pfmembrane.kernels.nodes import dirichlet_mask, nodal_spacing, raster_axes

RASTER = 0.5  # raster spacing / smallest nodal spacing of the old grid
# The smallest spacing, for the raster, is this quantile of the h_a: unlike the
# histogram peak of `spacing_peak` it moves continuously with the nodes. Two
# O12 grids 1e-9 apart had peaks 1.4% apart, which changed the raster and so
# moved the next grid's nodes by 1.6e-3. On the discocyte's O11 and O12 it lies
# 3-4% below the peak; on a uniform grid it is the peak.
RASTER_QUANTILE = 0.05


def raster(nodes, box, plane=None):
    """The axes (r, z) of the raster of the box (of its half z >= `plane` for a
    half-box solve) on which |grad phi_h| is tabulated, and the nodes'
    `nodal_spacing`, which sets its step."""
    h = nodal_spacing(nodes, plane=plane)
    step = RASTER * np.quantile(h, RASTER_QUANTILE)
    r, z = raster_axes(box, step, plane or 0.0)
    return r, z, h


def gradient_rows(r, z, nodes, phi, beta, cutoff, plane=None):
    """|grad phi_h| on the raster rows z (columns r); for `phi` of shape (K, N),
    K fields on the same nodes (a branch), the largest of their |grad phi_h|.
    `beta` is the locality phi_h was solved with."""
    R, Z = np.meshgrid(r, z, indexing='xy')
    points = np.column_stack([R.ravel(), Z.ravel()])
    basis = folded_basis(points, nodes, beta, cutoff, derivatives=1, plane=plane)
    d_r, d_z = (basis._replace(p=basis.dp[:, i]) for i in range(2))
    largest = np.zeros(len(points))
    for field in np.atleast_2d(phi):
        largest = np.maximum(largest, np.hypot(maxent.interpolate(d_r, field),
                                               maxent.interpolate(d_z, field)))
    return largest.reshape(len(z), len(r))


def dilate(values, r, z, band):
    """The largest of the raster `values` (rows z, columns r) within a distance
    `band` of each raster point. Max-ent's Laplacian errs where the spacing changes
    (runs/atlas/notes.md): a flat density keeps that out of the interface."""
    if band <= 0:
        return values
    dr, dz = r[1] - r[0], z[1] - z[0]
    kr, kz = int(np.ceil(band / dr)), int(np.ceil(band / dz))
    y, x = np.mgrid[-kz:kz + 1, -kr:kr + 1]
    return maximum_filter(values, footprint=np.hypot(x * dr, y * dz) <= band)


def cvt_nodes(nodes, box, grad, r, z, f, plane=None):
    """CVT nodes for rho = 1 + f |grad phi_h|, |grad phi_h| tabulated as `grad`
    on the raster (r, z): (nodes, Lloyd iterations, last movement). With a
    mirror `plane` the nodes fill the half box z >= plane and the tessellation
    is of that half, whose clipped cells are the mirror's."""
    # The tessellation works in [0, Rb] x [0, Zb - z0].
    shift = np.array([0.0, z[0]])

    def density(points):
        coords = [points[:, 1] / (z[1] - z[0]), points[:, 0] / (r[1] - r[0])]
        return 1.0 + f * map_coordinates(grad, coords, order=1, mode='nearest')

    new, iterations, movement = cvt.lloyd(nodes - shift, (box[0], box[1] - z[0]), density,
                                          mirror=plane is not None, axis=True)
    return new + shift, iterations, movement


def transfer(nodes, phi, beta, cutoff, new, box, plane=None):
    """phi_h of the nodal values `phi` (locality `beta`) at the nodes `new`,
    whose Dirichlet nodes get -1 exactly. Not collective."""
    basis = folded_basis(new, nodes, beta, cutoff, derivatives=0, plane=plane)
    values = maxent.interpolate(basis, phi)
    values[dirichlet_mask(new, box)] = -1.0
    return values
