"""Node adaptivity (paper Section 4.2, Appendix B): CVT relocation of the nodes
for rho = 1 + f |grad phi_h| of a solved field, and transfer of phi_h to them.
With a band w, |grad phi_h| is first replaced by its largest value within w,
so the density is flat across the interface and the nodes grade only where
phi_h is near +-1.

The density is tabulated once on a raster finer than the old grid's smallest
spacing (the ranks share the max-ent evaluations), then interpolated
bilinearly by every CVT step. The relocation itself runs on rank 0 and is
broadcast, so the new grid does not depend on the number of ranks.
"""
import time

import numpy as np
from scipy.ndimage import map_coordinates, maximum_filter

from pfmembrane.kernels import cvt, maxent
from pfmembrane.kernels.basis import folded_basis
from pfmembrane.kernels.nodes import dirichlet_mask, nodal_spacing, raster_axes, spacing_peak

RASTER = 0.5  # raster spacing / smallest nodal spacing of the old grid
# The smallest spacing, for the raster, is this quantile of the h_a: unlike the
# histogram peak of `spacing_peak` it moves continuously with the nodes. Two
# O12 grids 1e-9 apart had peaks 1.4% apart, which changed the raster and so
# moved the next grid's nodes by 1.6e-3. On the discocyte's O11 and O12 it lies
# 3-4% below the peak; on a uniform grid it is the peak.
RASTER_QUANTILE = 0.05


def gradient_raster(comm, nodes, phi, box, beta, cutoff, h, plane=None):
    """|grad phi_h| on a regular raster of the box (of its half z >= `plane`
    for a half-box solve), and the raster's axes; for `phi` of shape (K, N),
    K fields on the same nodes (a branch), the largest of their |grad phi_h|.

    Collective (`comm` is an mpi4py communicator): each rank evaluates a
    share of the raster rows. `beta` is the locality phi_h was solved with,
    `h` the nodes' `nodal_spacing` (it sets the raster step).
    """
    step = RASTER * np.quantile(h, RASTER_QUANTILE)
    r, z = raster_axes(box, step, plane or 0.0)
    mine = np.array_split(np.arange(len(z)), comm.Get_size())[comm.Get_rank()]
    R, Z = np.meshgrid(r, z[mine], indexing='xy')
    points = np.column_stack([R.ravel(), Z.ravel()])
    basis = folded_basis(points, nodes, beta, cutoff, derivatives=1, plane=plane)
    d_r, d_z = (basis._replace(p=basis.dp[:, i]) for i in range(2))
    largest = np.zeros(len(points))
    for field in np.atleast_2d(phi):
        largest = np.maximum(largest, np.hypot(maxent.interpolate(d_r, field),
                                               maxent.interpolate(d_z, field)))
    rows = comm.allgather(largest.reshape(len(mine), len(r)))
    return r, z, np.vstack(rows)


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


def relocate(comm, nodes, phi, box, beta, cutoff, f, plane=None, along=None, band=0.0):
    """CVT nodes for rho = 1 + f |grad phi_h| and phi_h transferred to them;
    with `along` (K, N), fields on the same nodes such as the other points of
    a branch, rho = 1 + f max |grad phi_h| over `phi` and them; with `band`
    > 0, rho = 1 + f max of that within `band` (`dilate`).

    Collective (`comm` is an mpi4py communicator). `phi` holds the values at
    every node, Dirichlet nodes included, and `beta` the locality of its
    basis. With a mirror `plane` the nodes fill the half box z >= plane and
    the tessellation is of that half, whose clipped cells are the mirror's.
    Returns (nodes, phi, info) with the same node count; the new Dirichlet
    nodes hold -1 exactly.
    """
    t0 = time.perf_counter()
    fields = phi if along is None else np.vstack([phi, along])
    h = nodal_spacing(nodes, plane=plane)
    r, z, grad = gradient_raster(comm, nodes, fields, box, beta, cutoff, h, plane)
    grad = dilate(grad, r, z, band)
    t_raster = time.perf_counter() - t0
    # The tessellation works in [0, Rb] x [0, Zb - z0].
    shift = np.array([0.0, z[0]])

    def density(points):
        coords = [points[:, 1] / (z[1] - z[0]), points[:, 0] / (r[1] - r[0])]
        return 1.0 + f * map_coordinates(grad, coords, order=1, mode='nearest')

    moved = None
    if comm.Get_rank() == 0:
        moved = cvt.lloyd(nodes - shift, (box[0], box[1] - z[0]), density,
                          mirror=plane is not None, axis=True)
    new, iterations, movement = comm.bcast(moved, root=0)
    new = new + shift
    new_phi = transfer(nodes, phi, beta, cutoff, new, box, plane)
    info = dict(f=float(f), band=float(band), iterations=iterations, movement=movement,
                raster=grad.shape,
                time_raster=t_raster, time=time.perf_counter() - t0,
                h_min=(spacing_peak(h),
                       spacing_peak(nodal_spacing(new, plane=plane))))
    return new, new_phi, info


def transfer(nodes, phi, beta, cutoff, new, box, plane=None):
    """phi_h of the nodal values `phi` (locality `beta`) at the nodes `new`,
    whose Dirichlet nodes get -1 exactly. Not collective."""
    basis = folded_basis(new, nodes, beta, cutoff, derivatives=0, plane=plane)
    values = maxent.interpolate(basis, phi)
    values[dirichlet_mask(new, box)] = -1.0
    return values
