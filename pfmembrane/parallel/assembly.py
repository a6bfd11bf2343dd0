"""PETSc layer: functionals of a distributed nodal Vec, gradients into Vecs,
Hessians into the bordered AIJ matrix [[H, -C^T], [-C, D]].

The only module that moves data between ranks during a solve: ghost values
arrive by forward scatters, gradient contributions leave by reverse
scatter-adds, Hessian rows owned elsewhere travel through MatSetValues' stash.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from pfmembrane.kernels.functionals import Functionals


class Assembly:
    """Energy and constraints of one scene on one grid, on distributed Vecs.

    Collective. `targets` = (A0, V0). The moments pin the rigid motions the
    scene leaves free: on the full box M = 0 (translation along the axis), on
    a half-box grid its mirror plane makes M vanish; where the forms carry a
    moment across the axis (`grad_X`: harmonics with m = 1), X is held where
    the start puts it (`hold`). The unknowns are the free nodal values
    (Dirichlet nodes are eliminated), in the layout's global numbering.
    """

    # The stage-2 Jacobian is this matrix itself, factored (`jacobian_operator`).
    krylov = False
    # where each constraint sits in the values (E, A, V, M, X[, Theta])
    VALUE_INDEX = {'A': 1, 'V': 2, 'M': 3, 'X': 4, 'Theta': 5}

    def __init__(self, grid, eps, k, c0, targets, zc, forms=None, layout=None):
        self.grid, self.layout = grid, layout or grid.layout
        self.comm = grid.comm
        self.mpi = self.comm.tompi4py()
        self.eps = eps
        self.forms = forms or Functionals(grid.ops, eps, k, c0, zc, lambda: grid.gram)
        local = {'M': self.forms.grad_M} if grid.plane is None else {}
        if getattr(self.forms, 'grad_X', None) is not None:
            local['X'] = self.forms.grad_X
        self.moments = tuple(local)
        self.targets = np.array([*targets] + [0.0 if m == 'M' else np.nan for m in local])
        self.volume_box = np.pi * grid.box[0] ** 2 * grid.box[1]
        self._ghosted = self.layout.create_ghosted()
        self.grad_V = self._to_global(self.forms.grad_V)
        self.grad_moments = [self._to_global(g) for g in local.values()]
        self._K = None
        self._pattern = None
        self.log = {name: PETSc.Log.Event('pf' + name) for name in
                    ('Functional', 'Gradient', 'Hessian', 'MatAssembly')}

    # -- vectors ---------------------------------------------------------------
    def create_vec(self):
        return self.layout.create_vec()

    def local(self, x):
        """Owned + ghost values of the global Vec x (a fresh array)."""
        g = self._ghosted
        x.copy(g)
        g.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with g.localForm() as loc:
            return loc.getArray(readonly=True).copy()

    def _to_global(self, local_values, out=None):
        """Sum rank-local nodal contributions (ghosts included) into a global Vec."""
        g = self._ghosted
        with g.localForm() as loc:
            loc.setArray(local_values)
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out = out if out is not None else self.create_vec()
        out.setArray(g.getArray(readonly=True))
        return out

    def _sum(self, local):
        return self.mpi.allreduce(local)

    # -- functionals -----------------------------------------------------------
    def values(self, x):
        """Global (E, A, V, M, X) at x."""
        with self.log['Functional']:
            v = self._sum(self.forms.values(self.local(x)))
        return self._full_box(v, x)

    def _full_box(self, v, x):
        """(E, A, V, M, X) from the summed parts: V gets its |Omega| / 2 and, on
        a half box, M is the mirror's zero, not the half's moment; X, linear in
        x, is 0 without a moment across the axis."""
        v[2] += 0.5 * self.volume_box
        if 'M' not in self.moments:
            v[3] = 0.0
        X = self.grad_moments[self.moments.index('X')].dot(x) if 'X' in self.moments else 0.0
        return np.append(v, X)

    @property
    def ncon(self):
        return len(self.targets)

    @property
    def constrained(self):
        """Where the constraints (A, V, moments) sit in the values."""
        return np.array([self.VALUE_INDEX[c] for c in ('A', 'V', *self.moments)])

    def hold(self, x):
        """Hold the rigid motions the moments pin where the start x puts them:
        X's target, X being linear in x (M's is 0, the scene's centre). Collective."""
        if 'X' in self.moments:
            j = self.moments.index('X')
            self.targets[j + 2] = self.grad_moments[j].dot(x)

    def constraint_gradients(self, gA):
        """The constraints' gradients [grad A, grad V, moments...] given grad A."""
        return [gA, self.grad_V, *self.grad_moments]

    def constraints(self, vals):
        """The constrained values (A, V, moments) among `vals` (E, A, V, M, X)."""
        return np.asarray(vals)[self.constrained]

    def max_abs_phi(self, x):
        """max |phi_h| over every rank's quadrature points. Not the nodal values: a
        max-ent basis does not interpolate, and where nodes crowd (a CVT along a
        mirror plane) nodal values can oscillate while phi_h stays smooth."""
        o = self.forms.ops
        u = o.B0 @ self.local(x) + o.b0
        return self.mpi.allreduce(float(np.abs(u).max(initial=0.0)), op=MPI.MAX)

    def gradients(self, x, gE, gA):
        """Global (E, A, V, M) at x; fills gE and gA. grad V, grad M are constant."""
        with self.log['Gradient']:
            vals, lE, lA = self.forms.gradients(self.local(x))
            self._to_global(lE, gE)
            self._to_global(lA, gA)
            v = self._sum(vals)
        return self._full_box(v, x)

    # -- bordered matrix -------------------------------------------------------
    def bordered_matrix(self):
        """The AIJ matrix [[H, -C^T], [-C, D]] with exact preallocation (built once).

        Collective. The last rank owns the ncon multiplier rows.
        """
        if self._K is None:
            self._K = self._create_bordered()
        return self._K

    def _create_bordered(self):
        lay, mpi, ncon = self.layout, self.mpi, self.ncon
        size, rank = mpi.Get_size(), mpi.Get_rank()
        n, last = lay.nglobal, rank == size - 1
        P = self.local_pattern().tocoo()
        rows, cols = lay.local_numbers[P.row], lay.local_numbers[P.col]
        starts = np.array(mpi.allgather(lay.start) + [n])
        dest = np.searchsorted(starts, rows, side='right') - 1
        # Rows touched here but owned elsewhere: send their pattern to the owner.
        order = np.argsort(dest, kind='stable')
        keys = (rows * (n + ncon) + cols)[order]
        counts = np.bincount(dest, minlength=size)
        recv_counts = np.array(mpi.alltoall(counts.tolist()))
        recv = np.empty(recv_counts.sum(), dtype=np.int64)
        mpi.Alltoallv([keys.astype(np.int64), counts], [recv, recv_counts])
        keys = np.unique(recv)
        r, c = keys // (n + ncon) - lay.start, keys % (n + ncon)
        nrows = lay.nowned + (ncon if last else 0)
        border = np.arange(n, n + ncon)
        counts_r = np.bincount(r, minlength=lay.nowned)
        # Each owned row: its (sorted) Hessian columns, then the ncon border columns.
        indptr = np.concatenate([[0], np.cumsum(counts_r + ncon)])
        indices = np.empty(indptr[-1], dtype=np.int64)
        indices[np.arange(len(c)) + ncon * r] = c
        for j in range(ncon):
            indices[indptr[1:] - ncon + j] = n + j
        if last:  # dense multiplier rows: every unknown and the diagonal block
            dense = np.arange(n + ncon)
            indptr = np.concatenate([indptr, indptr[-1] + (n + ncon) * np.arange(1, ncon + 1)])
            indices = np.concatenate([indices] + [dense] * ncon)
        K = PETSc.Mat().create(comm=self.comm)
        K.setSizes(((nrows, n + ncon), (nrows, n + ncon)))
        K.setType(PETSc.Mat.Type.AIJ)
        K.setPreallocationCSR((indptr.astype(PETSc.IntType), indices.astype(PETSc.IntType)))
        K.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, True)
        K.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        lg = np.concatenate([lay.local_numbers, border]).astype(PETSc.IntType)
        K.setLGMap(PETSc.LGMap().create(lg, comm=self.comm))
        return K

    def assemble_bordered(self, x, sigma, C, diag, keep=False):
        """K = [[Hess E - sigma Hess A, -C^T], [-C, diag I]] at x.

        Collective. C is the list of ncon constraint-gradient Vecs. `keep`:
        K stays as it is, and so does its factorization (where the Jacobian
        is an action, `krylov`, K only preconditions it: `Solver`).
        """
        K = self.bordered_matrix()
        if keep:
            return K
        lay, ncon = self.layout, self.ncon
        with self.log['Hessian']:
            H = self.forms.hessian(self.local(x), sigma)
        with self.log['MatAssembly']:
            K.zeroEntries()
            K.setValuesLocalCSR(*self._hessian_pattern(), H.data, addv=PETSc.InsertMode.ADD)
            Cown = -np.column_stack([c.getArray(readonly=True) for c in C])
            m, nl = lay.nowned, lay.nlocal
            K.setValuesLocalCSR(np.arange(0, ncon * m + 1, ncon, dtype=PETSc.IntType),
                                np.tile(np.arange(nl, nl + ncon), m).astype(PETSc.IntType),
                                Cown.ravel(), addv=PETSc.InsertMode.ADD)
            own = np.arange(m, dtype=PETSc.IntType)
            for j in range(ncon):
                K.setValuesLocal([nl + j], own, Cown[:, j], addv=PETSc.InsertMode.ADD)
            if self.comm.getRank() == self.comm.getSize() - 1:
                for j in range(ncon):
                    K.setValuesLocal(nl + j, nl + j, diag, addv=PETSc.InsertMode.ADD)
            K.assemble()
        return K

    def local_pattern(self):
        """The local Hessian's sparsity (CSR, local numbering)."""
        return self.grid.gram.pattern

    def jacobian_operator(self):
        """The stage-2 Jacobian's operator: the bordered matrix."""
        return self.bordered_matrix()

    def _hessian_pattern(self):
        """Row pointers and columns of every local Hessian (one pattern per grid),
        in PETSc's integer type, converted once."""
        if self._pattern is None:
            P = self.local_pattern()
            self._pattern = (P.indptr.astype(PETSc.IntType), P.indices.astype(PETSc.IntType))
        return self._pattern

    def destroy(self):
        """Free the PETSc objects built here."""
        for obj in (self._K, self._ghosted):
            if obj is not None:
                obj.destroy()

    def shift_hessian(self, delta):
        """Add delta to the diagonal of the Hessian block of the bordered matrix."""
        K = self.bordered_matrix()
        d = K.createVecLeft()
        d.getArray()[:self.layout.nowned] = delta
        K.setDiagonal(d, addv=PETSc.InsertMode.ADD)
