"""Ownership of the free nodes among the ranks, carried by a PETSc DMShell.

Every rank holds the node coordinates (per-node data is small). Each rank owns
a contiguous block of the free unknowns, renumbered after a coordinate
bisection (or a graph partition of the Delaunay adjacency), owns the
background cells nearest to its nodes, and sees as ghosts the off-rank
free nodes its quadrature points touch.
"""
import numpy as np
from petsc4py import PETSc
from scipy.spatial import cKDTree


def _graph(n, triangles):
    """Symmetric adjacency (CSR) of the triangles' edges, without the diagonal."""
    i = triangles[:, [0, 1, 2, 1, 2, 0]].ravel()
    j = triangles[:, [1, 2, 0, 0, 1, 2]].ravel()
    key = np.unique(i * n + j)
    indptr = np.concatenate([[0], np.cumsum(np.bincount(key // n, minlength=n))])
    return indptr, key % n


def bisection(points, parts):
    """Part (0 ... parts - 1) of each point by recursive coordinate bisection:
    each set is cut across its longer extent at the point count that splits
    its parts in two (ties broken by the other coordinate, then the index),
    so the parts differ in size by at most one and the result is a function
    of the points alone. Not collective."""
    part = np.zeros(len(points), dtype=np.int64)

    def cut(idx, first, n):
        if n == 1:
            part[idx] = first
            return
        axis = int(np.argmax(np.ptp(points[idx], axis=0)))
        idx = idx[np.lexsort((idx, points[idx, 1 - axis], points[idx, axis]))]
        k = len(idx) * (n // 2) // n
        cut(idx[:k], first, n // 2)
        cut(idx[k:], first + n // 2, n - n // 2)

    cut(np.arange(len(points)), 0, parts)
    return part


def partition_free_nodes(comm, nodes, free, triangles, method='bisection'):
    """Rank owning each free node (in node order).

    Collective. `method` 'bisection': the coordinate `bisection` of the free
    nodes, the same partition in every run, so that the assembly sums in the
    same order every time (parallel MUMPS can still differ in the last bits,
    runs/api/README.md); any other, a PETSc MatPartitioning type (ptscotch) of the
    Delaunay graph of the free nodes, whose partitions change from run to run
    (PT-Scotch seeds itself from the clock).
    """
    size, rank = comm.getSize(), comm.getRank()
    nfree = int(free.sum())
    if size == 1:
        return np.zeros(nfree, dtype=np.int64)
    if method == 'bisection':
        return bisection(nodes[free], size)
    index = np.full(len(free), -1, dtype=np.int64)
    index[free] = np.arange(nfree)
    indptr, cols = _graph(nfree, index[triangles[free[triangles].all(axis=1)]])
    lo, hi = nfree * rank // size, nfree * (rank + 1) // size
    adj = PETSc.Mat().createAIJ(
        size=((hi - lo, nfree), (hi - lo, nfree)), comm=comm,
        csr=((indptr[lo:hi + 1] - indptr[lo]).astype(PETSc.IntType),
             cols[indptr[lo]:indptr[hi]].astype(PETSc.IntType),
             np.ones(indptr[hi] - indptr[lo])))
    part = PETSc.MatPartitioning().create(comm)
    part.setAdjacency(adj)
    part.setType(method)
    new_is = PETSc.IS()
    part.apply(new_is)
    new_rank = new_is.getIndices().astype(np.int64)
    new_is.destroy()
    part.destroy()
    adj.destroy()
    return np.concatenate(comm.tompi4py().allgather(new_rank))


class Layout:
    """Global numbering of the free unknowns, their ghosts and PETSc vectors.

    Collective. `order[g]` is the node of global unknown g and `number[a]` the
    unknown of node a (-1 on Dirichlet nodes). Local arrays hold the owned
    unknowns first, then the ghosts in increasing global number.
    """

    def __init__(self, comm, nodes, free, triangles, cells, partition='bisection'):
        self.comm = comm
        rank = comm.getRank()
        owner = partition_free_nodes(comm, nodes, free, triangles, partition)
        free_nodes = np.flatnonzero(free)
        self.order = free_nodes[np.argsort(owner, kind='stable')]
        self.number = np.full(len(free), -1, dtype=np.int64)
        self.number[self.order] = np.arange(len(self.order))
        counts = np.bincount(owner, minlength=comm.getSize())
        self.start, self.nowned = int(counts[:rank].sum()), int(counts[rank])
        self.nglobal = len(self.order)
        # A background cell (M x 3 x 2) goes to the owner of the free node nearest
        # its centroid.
        nearest = cKDTree(nodes[free_nodes]).query(cells.mean(axis=1))[1]
        self.my_cells = cells[owner[nearest] == rank]
        self.dm = PETSc.DMShell().create(comm)
        self.dm.setGlobalVector(self.create_vec())

    def set_ghosts(self, touched):
        """Make the off-rank unknowns among `touched` (global numbers) ghosts."""
        g = np.unique(touched)
        self.ghosts = g[(g < self.start) | (g >= self.start + self.nowned)]
        self.local_numbers = np.concatenate(
            [np.arange(self.start, self.start + self.nowned), self.ghosts])
        self.nlocal = len(self.local_numbers)
        self.lgmap = PETSc.LGMap().create(self.local_numbers.astype(PETSc.IntType),
                                          comm=self.comm)

    def local_index(self, g):
        """Local index (owned, then ghosts) of global unknowns `g`."""
        owned = (g >= self.start) & (g < self.start + self.nowned)
        return np.where(owned, g - self.start,
                        self.nowned + np.searchsorted(self.ghosts, g))

    def create_vec(self):
        """A distributed vector over the free unknowns."""
        return PETSc.Vec().createMPI((self.nowned, self.nglobal), comm=self.comm)

    def vec(self, phi):
        """The Vec of the free values of nodal `phi` (every node)."""
        x = self.create_vec()
        x.setArray(np.asarray(phi)[self.order[self.start:self.start + self.nowned]])
        return x

    def create_ghosted(self):
        """A distributed vector with this rank's ghost entries appended locally."""
        return PETSc.Vec().createGhost(self.ghosts.astype(PETSc.IntType),
                                       size=(self.nowned, self.nglobal), comm=self.comm)

    def gather(self, vec):
        """The whole vector (indexed by global number) on rank 0, None elsewhere.

        Collective.
        """
        scatter, full = PETSc.Scatter.toZero(vec)
        scatter.scatter(vec, full, addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        out = full.getArray().copy() if self.comm.getRank() == 0 else None
        scatter.destroy()
        full.destroy()
        return out

    def nodal(self, vec, dirichlet):
        """Values at every node, on every rank, of a Vec of free values
        (`dirichlet` on the Dirichlet nodes). Collective."""
        values = self.gather(vec)
        out = None
        if values is not None:
            out = np.full(len(self.number), float(dirichlet))
            out[self.order] = values
        return self.comm.tompi4py().bcast(out, root=0)
