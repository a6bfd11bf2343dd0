"""PETSc layer of a field with azimuthal harmonics (`kernels.harmonics`).

The unknowns are the harmonics' free nodal values, interleaved node by node
(nh a + j), so each rank owns the harmonics of its own nodes and one ghost
scatter moves all of them; each scaled by rho_a^m (`kernels.harmonics`), which
`vec` and `nodal` apply and undo. The bordered matrix holds the block-diagonal
Hessian diag(H_m) of the theta-averaged state: stage 1's Newton steps use it
as a model Hessian (the line search and the inertia check keep them descent
steps), stage 2 as the preconditioner of a Krylov solver whose operator is
the exact bordered Hessian's action, never assembled.
"""
import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from pfmembrane.kernels.harmonics import HarmonicForms, unknown_scale
from pfmembrane.parallel.assembly import Assembly
from pfmembrane.parallel.multivector import MAIJProducts


class Interleaved:
    """A `partition.Layout`'s numbering with nh unknowns per free node.

    Collective. The same owned ranges, scaled by nh; local arrays reshape to
    (nodes, nh). `scale` (nodes x nh): chi = scale x, x the unknowns.
    """

    def __init__(self, layout, scale):
        self.base, self.scale, self.comm = layout, scale, layout.comm
        self.nh = nh = scale.shape[1]
        self.start, self.nowned, self.nglobal = nh * layout.start, nh * layout.nowned, \
            nh * layout.nglobal
        self.ghosts = self._expand(layout.ghosts)
        self.local_numbers = self._expand(layout.local_numbers)
        self.nlocal = len(self.local_numbers)

    def _expand(self, numbers):
        return (self.nh * np.asarray(numbers)[:, None] + np.arange(self.nh)).ravel()

    def create_vec(self):
        return PETSc.Vec().createMPI((self.nowned, self.nglobal), comm=self.comm)

    def create_ghosted(self):
        return PETSc.Vec().createGhost(self.ghosts.astype(PETSc.IntType),
                                       size=(self.nowned, self.nglobal), comm=self.comm)

    def local_scale(self):
        """`scale` at the local nodes (owned, then ghosts), one row per node."""
        return self.scale[self.base.order[self.base.local_numbers]]

    def vec(self, phi):
        """The Vec of nodal harmonics `phi` (nodes x nh, every node)."""
        b = self.base
        x = self.create_vec()
        owned = b.order[b.start:b.start + b.nowned]
        x.setArray((np.asarray(phi)[owned] / self.scale[owned]).ravel())
        return x

    def nodal(self, x, fill=-1.0):
        """Nodal harmonics (nodes x nh) on every rank: `fill` on the Dirichlet
        nodes for the axisymmetric harmonic, 0 for the others. Collective."""
        b, nh = self.base, self.nh
        part = b.create_vec()
        out = []
        for j in range(nh):
            part.setArray(x.getArray(readonly=True)[j::nh])
            out.append(b.nodal(part, fill if j == 0 else 0.0))
        part.destroy()
        # the Dirichlet nodes' fill is chi's (there the unknowns are not free)
        free = np.zeros(len(b.number), dtype=bool)
        free[b.order] = True
        phi = np.column_stack(out)
        phi[free] *= self.scale[free]
        return phi


class HarmonicAssembly(Assembly):
    """`Assembly` of a field with the harmonics `harmonics`. Collective.

    `coupled`: the bordered matrix holds the exact Hessian, every pair of
    harmonics coupled (nh^2 times the axisymmetric entries), and the solver
    factors it as it does an axisymmetric one (no Krylov solver, the inertia
    of every factorization exact: stage 1's shifts and the index)."""

    def __init__(self, grid, eps, k, c0, targets, zc, harmonics, coupled=False):
        if grid.plane is not None and np.any(harmonics.sine):
            raise ValueError("sines with a half box: not supported")
        layout = Interleaved(grid.layout, unknown_scale(grid.nodes, grid.h, harmonics))
        self.products = MAIJProducts(grid.ops, len(harmonics))
        forms = HarmonicForms(grid.ops, eps, k, c0, zc, harmonics, lambda: grid.gram, coupled,
                              layout.local_scale(), self.products)
        self.harmonics, self.krylov = harmonics, not coupled
        super().__init__(grid, eps, k, c0, targets, zc, forms=forms, layout=layout)
        if np.any(harmonics.sine):
            # the phase condition: its gradient, the start's rotation generator, set by `hold`
            self.moments += ('Theta',)
            self.grad_moments.append(self.create_vec())
            self.targets = np.append(self.targets, 0.0)
        self._state = None
        self._shift = 0.0
        self._J = None

    def local_pattern(self):
        return self.forms.pattern()

    def destroy(self):
        super().destroy()
        self.products.destroy()
        if self._J is not None:
            self._J.destroy()

    def _full_box(self, v, x):
        """(E, A, V, M, X[, Theta]): with sines, the phase Theta (`hold`)."""
        v = super()._full_box(v, x)
        return np.append(v, self.grad_moments[-1].dot(x)) if 'Theta' in self.moments else v

    def hold(self, x):
        """`Assembly.hold`, and with sines the rotation about the axis: the
        phase condition Theta = t . x / |t|^2 = 0 with t = -d x / d theta at
        the start x (pde2path's phase condition; the shape turned by alpha is
        phi(theta - alpha) = x + alpha t + ...), to first order the angle by
        which the shape turned from the start (t . x = 0 there: sum m (x_c x_s
        - x_s x_c)). Collective."""
        super().hold(x)
        if 'Theta' not in self.moments:
            return
        h = self.harmonics
        own = x.getArray(readonly=True).reshape(-1, len(h))
        t = np.zeros_like(own)
        for k in np.flatnonzero(h.sine):
            j = np.flatnonzero(~h.sine & (h.m == h.m[k]))[0]
            # -d/dtheta (a cos m theta + b sin m theta) = -m b cos m theta + m a sin m theta;
            # a harmonic's cosine and sine share their scale rho^-m
            t[:, j], t[:, k] = -h.m[k] * own[:, k], h.m[k] * own[:, j]
        g = self.grad_moments[-1]
        g.setArray(t.ravel())
        norm2 = g.dot(g)
        if norm2 == 0.0:
            raise ValueError("sines need a start that is not axisymmetric: at an axisymmetric "
                             "one no phase fixes the rotation about the axis")
        g.scale(1.0 / norm2)

    def max_abs_phi(self, x):
        return self.mpi.allreduce(self.forms.max_abs(self.local(x)), op=MPI.MAX)

    def assemble_bordered(self, x, sigma, C, diag, keep=False):
        """The bordered matrix (block-diagonal, or `coupled`), and the state
        of the exact operator (`jacobian_operator`), which moves to x also
        where the matrix is kept."""
        if self.krylov:
            self._state = (self.forms.linearization(self.local(x), sigma), C, diag)
        self._shift = 0.0
        return super().assemble_bordered(x, sigma, C, diag, keep)

    def shift_hessian(self, delta):
        """Shift the model's diagonal and the exact action alike."""
        self._shift += delta
        super().shift_hessian(delta)

    def jacobian_operator(self):
        """A shell matrix: [[H, -C^T], [-C, diag]] applied, H the exact Hessian
        of E - sigma A at the last `assemble_bordered` state (`coupled`: the
        bordered matrix itself)."""
        if not self.krylov:
            return self.bordered_matrix()
        if self._J is None:
            K = self.bordered_matrix()
            self._J = PETSc.Mat().createPython(K.getSizes(), _BorderedAction(self),
                                               comm=self.comm)
            self._J.setUp()
        return self._J

    def hessian_action(self, v, out):
        """out = H v at the last state (v, out distributed Vecs)."""
        with self.log['Hessian']:
            local = self._state[0](self.local(v))
        self._to_global(local, out)
        if self._shift:
            out.axpy(self._shift, v)
        return out


class _BorderedAction:
    """The shell's context: the bordered Hessian's action through the kernel."""

    def __init__(self, assembly):
        self.a = assembly
        self.v, self.hv = assembly.create_vec(), assembly.create_vec()

    def mult(self, mat, X, Y):
        a = self.a
        nl, ncon = a.layout.nowned, a.ncon
        size = a.comm.getSize()
        last = a.comm.getRank() == size - 1
        self.v.setArray(X.getArray(readonly=True)[:nl])
        dnu = a.mpi.bcast(X.getArray(readonly=True)[nl:].copy() if last else None,
                          root=size - 1)
        _, C, diag = a._state
        a.hessian_action(self.v, self.hv)
        for j in range(ncon):
            self.hv.axpy(-dnu[j], C[j])
        y = Y.getArray()
        y[:nl] = self.hv.getArray(readonly=True)
        dots = [c.dot(self.v) for c in C]
        if last:
            y[nl:] = -np.array(dots) + diag * np.asarray(dnu)
