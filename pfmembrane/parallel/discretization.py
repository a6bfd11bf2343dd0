"""One grid: nodes, max-ent basis at this rank's quadrature points, operators.

Everything here is built once per node set and reused by every functional,
every iteration and every eps on that grid.
"""
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from pfmembrane.kernels import nodes as nodesets, quadrature
from pfmembrane.kernels.gram import Gram
from pfmembrane.kernels.basis import folded_basis, spacing_and_locality
from pfmembrane.parallel.partition import Layout

POINT_CHUNK = 16384  # quadrature points per max-ent evaluation: bounds the working memory


class Operators(NamedTuple):
    """Rank-local maps from local nodal values to fields at local quadrature points.

    u = B0 @ phi + b0 (value), ur, uz (gradient), lap (axisymmetric Laplacian
    u_rr + u_r / r + u_zz); the offsets b* carry the Dirichlet nodes at -1.
    """
    B0: sp.csr_matrix
    Br: sp.csr_matrix
    Bz: sp.csr_matrix
    BL: sp.csr_matrix
    b0: np.ndarray
    br: np.ndarray
    bz: np.ndarray
    bL: np.ndarray
    w: np.ndarray
    r: np.ndarray
    z: np.ndarray


class Discretization:
    """A node set with its max-ent basis, partition and local operators.

    Collective. Parameters are plain values: `box` = (Rb, Zb), `gamma` the
    locality, `cutoff` the support cut-off exp(-beta_a d^2) >= cutoff, `degree`
    the Gauss rule on the Delaunay triangles, `smoothing` the passes over the
    nodal spacing behind beta_a, `floor` its quantile below which beta_a stays
    constant (`basis.spacing_and_locality`). `h` is the unsmoothed spacing. With
    a mirror `plane` the nodes fill the half box z >= plane, phi is even across
    it and the quadrature weights count both halves, so integrals are full-box
    ones.
    """

    def __init__(self, comm, nodes, box, gamma=0.8, cutoff=1e-6, degree=4, smoothing=0,
                 plane=None, partition='bisection', floor=0.0):
        self.comm, self.nodes, self.box = comm, nodes, tuple(box)
        self.gamma, self.cutoff, self.degree = gamma, cutoff, degree
        self.plane = plane
        self.h, self.beta = spacing_and_locality(nodes, gamma, smoothing, plane, floor)
        self.dirichlet = nodesets.dirichlet_mask(nodes, box)
        self.triangles = quadrature.triangulate(nodes)
        self.layout = Layout(comm, nodes, ~self.dirichlet, self.triangles,
                             quadrature.cells(nodes, self.triangles, plane), partition)
        cells = self.layout.my_cells
        points, weights = quadrature.rule(cells, degree)
        if plane is not None:
            weights = 2.0 * weights
        self.per_cell = len(points) // max(len(cells), 1)
        self.nquad = comm.tompi4py().allreduce(len(points))
        self.ops = self._operators(points, weights)
        self._gram = None

    def _operators(self, points, weights):
        """The operators, built POINT_CHUNK quadrature points at a time so that
        only one chunk's basis is ever held: the peak memory is about that of
        the operators themselves."""
        names = ('B0', 'Br', 'Bz', 'BL')
        pieces = [self._chunk(points[start:start + POINT_CHUNK])
                  for start in range(0, len(points), POINT_CHUNK)]
        layout = self.layout
        layout.set_ghosts(np.unique(np.concatenate([c['ghosts'] for c in pieces])))
        indptr = np.concatenate([[0], np.cumsum(np.concatenate([c['counts'] for c in pieces]))])
        indices = np.concatenate([layout.local_index(c.pop('columns')).astype(np.int32)
                                  for c in pieces])
        shape = (len(points), layout.nlocal)
        ops = {}
        for k, name in enumerate(names):
            # One index array for all four: they share one sorted, duplicate-free pattern.
            data = np.concatenate([c['data'][k] for c in pieces])
            for c in pieces:
                c['data'][k] = None
            ops[name] = sp.csr_matrix((data, indices, indptr), shape=shape, copy=False)
            ops[name].has_sorted_indices = True
            ops['b' + name[1:]] = np.concatenate([c['offsets'][k] for c in pieces])
        return Operators(w=weights, r=points[:, 0], z=points[:, 1], **ops)

    def _chunk(self, points):
        """Operator rows at some quadrature points: per point the count of free
        nodes, their global numbers sorted as their local indices will be, the
        four operators' values (a node's mirror images summed), and the
        constant contributions of the Dirichlet nodes (phi = -1)."""
        basis = folded_basis(points, self.nodes, self.beta, self.cutoff, derivatives=2,
                             plane=self.plane)
        rows = np.repeat(np.arange(len(points)), np.diff(basis.indptr))
        r = points[rows, 0]
        values = (basis.p, basis.dp[:, 0], basis.dp[:, 1],
                  basis.ddp[:, 0] + basis.dp[:, 0] / r + basis.ddp[:, 2])
        fixed = self.dirichlet[basis.indices]
        offsets = [-np.bincount(rows[fixed], weights=v[fixed], minlength=len(points))
                   for v in values]
        lay = self.layout
        g = lay.number[basis.indices[~fixed]]
        # Local indices put owned unknowns first, then ghosts, each ascending:
        # this key orders global numbers the same way.
        owned = (g >= lay.start) & (g < lay.start + lay.nowned)
        span = 2 * lay.nglobal + 1
        keys, entry = np.unique(rows[~fixed] * span + np.where(owned, g - lay.start, lay.nglobal + g),
                                return_inverse=True)
        row, key = np.divmod(keys, span)
        columns = np.where(key < lay.nglobal, key + lay.start, key - lay.nglobal)
        data = [np.bincount(entry, weights=v[~fixed], minlength=len(keys)) for v in values]
        return dict(counts=np.bincount(row, minlength=len(points)), columns=columns, data=data,
                    offsets=offsets, ghosts=np.unique(g[~owned]))

    def hessian_pattern(self):
        """Local (nlocal x nlocal) sparsity of B^T diag(c) B, free of cancellation."""
        S = abs(self.ops.B0) + abs(self.ops.Br) + abs(self.ops.Bz) + abs(self.ops.BL)
        S.data[:] = 1.0
        P = (S.T @ S).tocsr()
        P.sort_indices()
        return P

    @property
    def gram(self):
        """Batched Hessian products on this grid; built on first use, so a
        gradient-only solve never pays for them."""
        if self._gram is None:
            o = self.ops
            self._gram = Gram({'B0': o.B0, 'BL': o.BL, 'Br': o.Br, 'Bz': o.Bz},
                              self.per_cell, self.hessian_pattern())
        return self._gram
