"""The collective side of node adaptivity (`kernels.adapt`): the ranks share
the raster of |grad phi_h|, rank 0 relocates the nodes and broadcasts them, so
the new grid does not depend on the number of ranks."""
import time

import numpy as np

from pfmembrane.kernels.adapt import cvt_nodes, dilate, gradient_rows, raster, transfer
from pfmembrane.kernels.nodes import nodal_spacing, spacing_peak


def gradient_raster(comm, nodes, phi, box, beta, cutoff, plane=None):
    """|grad phi_h| on the raster of `kernels.adapt.raster` and its axes, each
    rank evaluating a share of its rows; the nodes' spacing. Collective
    (`comm` an mpi4py communicator)."""
    r, z, h = raster(nodes, box, plane)
    mine = np.array_split(np.arange(len(z)), comm.Get_size())[comm.Get_rank()]
    rows = comm.allgather(gradient_rows(r, z[mine], nodes, phi, beta, cutoff, plane))
    return r, z, np.vstack(rows), h


def relocate(comm, nodes, phi, box, beta, cutoff, f, plane=None, along=None, band=0.0):
    """CVT nodes for rho = 1 + f |grad phi_h| and phi_h transferred to them;
    with `along` (K, N), fields on the same nodes such as the other points of
    a branch, rho = 1 + f max |grad phi_h| over `phi` and them; with `band`
    > 0, rho = 1 + f max of that within `band` (`kernels.adapt.dilate`).

    Collective (`comm` an mpi4py communicator). `phi` holds the values at
    every node, Dirichlet nodes included, and `beta` the locality of its
    basis; `plane` a mirror plane (`kernels.adapt.cvt_nodes`). Returns (nodes,
    phi, info) with the same node count; the new Dirichlet nodes hold -1
    exactly.
    """
    t0 = time.perf_counter()
    fields = phi if along is None else np.vstack([phi, along])
    r, z, grad, h = gradient_raster(comm, nodes, fields, box, beta, cutoff, plane)
    grad = dilate(grad, r, z, band)
    t_raster = time.perf_counter() - t0
    moved = cvt_nodes(nodes, box, grad, r, z, f, plane) if comm.Get_rank() == 0 else None
    new, iterations, movement = comm.bcast(moved, root=0)
    new_phi = transfer(nodes, phi, beta, cutoff, new, box, plane)
    info = dict(f=float(f), band=float(band), iterations=iterations, movement=movement,
                raster=grad.shape,
                time_raster=t_raster, time=time.perf_counter() - t0,
                h_min=(spacing_peak(h),
                       spacing_peak(nodal_spacing(new, plane=plane))))
    return new, new_phi, info
