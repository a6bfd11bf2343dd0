"""Azimuthal stability modes of an axisymmetric state: H_m as distributed
PETSc matrices, their index by MUMPS inertia, their lowest eigenpairs by SLEPc.

Per mode m the generalized problem H_m psi = lambda M_m psi is solved, M_m the
L2 mass of the 3D perturbation psi cos(m theta) (`kernels.azimuthal`): lambda is
the second variation of L = E - nu . (c - c0) per unit squared L2 norm. For
m = 0 the perturbation must keep A, V (and M on the full box): the problem is
bordered, [[H_0, C^T], [C, 0]] with B = [[M_0, 0], [0, 0]], whose inertia
counts the constraints' ncon negative eigenvalues besides the tangent space's.
For m >= 1 the constraints drop out: the border rows carry the identity, so
that one matrix layout (the solver's bordered one) serves every m.

One MUMPS LDL^T factorization of K = H_m - sigma M_m per mode gives both the
inertia (the index: eigenvalues below sigma = 0) and the shift-and-invert
transformation of the eigensolver, which sees K with target 0. M_m is never
assembled: it enters K as one more weight of the Gram products that build
H_m, and SLEPc applies it as B0^T diag(t_m w r^(2m)) B0, a shell matrix (two
sparse products per application, against a Gram product per m).
"""
import time
from typing import NamedTuple

import numpy as np
from petsc4py import PETSc

from pfmembrane.kernels import azimuthal as kernel
from pfmembrane.parallel.solver import gram

MAX_SHIFTS = 40  # factorizations per m, should the shift have to move far below 0


class Spectrum(NamedTuple):
    """One mode's stability: `index` the number of negative eigenvalues (on
    the constraints' tangent space for m = 0), `eigenvalues` the lowest ones
    ascending, `vectors` their modes as distributed Vecs of chi (psi = r^m chi,
    M_m-normalized: t_m int psi^2 r dr dz = 1), `rigid` the fraction of each
    mode's squared norm in the span of mode m's rigid motions
    (`kernels.azimuthal.ModeForms.rigid`: m = 0 and 1; NaN for other m), `time`
    the seconds spent on this m (assembly, factorizations, eigensolve)."""
    m: int
    index: int
    eigenvalues: np.ndarray
    vectors: list
    rigid: np.ndarray
    time: float


class _Mass:
    """Context of the shell matrix B = [[M_m, 0], [0, 0]] on the bordered
    layout: ghost values in by a forward scatter, contributions out by a
    reverse scatter-add, zero on the multiplier rows."""

    def __init__(self, forms, layout):
        self.forms, self.nown = forms, layout.nowned
        self.ghosted = layout.create_ghosted()
        self.weights = None

    def mult(self, mat, x, y):
        g = self.ghosted
        g.getArray()[:] = x.getArray(readonly=True)[:self.nown]
        g.ghostUpdate(addv=PETSc.InsertMode.INSERT, mode=PETSc.ScatterMode.FORWARD)
        with g.localForm() as loc:
            loc.setArray(self.forms.mass(loc.getArray(readonly=True), self.weights))
        g.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        out = y.getArray()
        out[:self.nown] = g.getArray(readonly=True)
        out[self.nown:] = 0.0


class ModeAnalysis:
    """The mode Hessians of one converged state of a `parallel.problem.Problem`
    (`Problem.modes`, which destroys it when it closes). Collective.

    `phi` is the state's nodal values at every node, `nu_area` its tension,
    `nev` the eigenpairs wanted per m. The eigensolver reads its options under
    the problem's prefix + 'modes_' (`-PREFIXmodes_eps_tol`), where the MUMPS
    LDL^T defaults go (`-PREFIXmodes_st_mat_mumps_icntl_7`). The per-triangle
    blocks of the four operators (`Gram.blocks`) are taken here, once for
    every m.
    """

    def __init__(self, owner, phi, nu_area, nev=3):
        grid, scene, eps = owner.grid, owner.scene, owner.eps
        d = grid.discrete
        self.prefix = owner.prefix + 'modes_'
        self.comm, self.layout, self.nev = grid.comm, d.layout, nev
        self.half = d.plane is not None
        self.problem = owner.assembly
        lay = self.layout
        x = self.problem.create_vec()
        x.setArray(np.asarray(phi)[lay.order[lay.start:lay.start + lay.nowned]])
        gA = x.duplicate()
        self.problem.gradients(x, x.duplicate(), gA)
        self.C = self.problem.constraint_gradients(gA)
        self.forms = kernel.ModeForms(d.ops, d.gram, d.gram.blocks(kernel.OPERATORS),
                                      self.problem.local(x), eps, scene.k, scene.c0, nu_area,
                                      scene.zc)
        self.K = self.problem.bordered_matrix()
        self._mass = _Mass(self.forms, lay)
        self.B = PETSc.Mat().createPython(self.K.getSizes(), self._mass, comm=self.comm)
        self.B.setUp()
        P = d.gram.pattern
        self._pattern = (P.indptr.astype(PETSc.IntType), P.indices.astype(PETSc.IntType))
        self._solver, self._previous = None, []
        owner.options.mumps('modes_st_')

    def assemble(self, m, shift=0.0):
        """K = [[H_m - shift M_m, C^T], [C, 0]] (m = 0) or [[H_m - shift M_m,
        0], [0, I]] (m >= 1); B applies M_m from now on. Collective.

        r^m spans many decades (the mass diagonal 1e-21 ... 0.05 at m = 6 on
        2,512 nodes), but MUMPS' own scaling copes: a diag(M_m)^(-1/2)
        congruence gave the same inertia, no zero pivots either way, and the
        same eigenvalues to every printed digit.
        """
        K, lay = self.K, self.layout
        ncon, nown, nloc = len(self.C), lay.nowned, lay.nlocal
        K.zeroEntries()
        K.setValuesLocalCSR(*self._pattern, self.forms.hessian(m, shift).data,
                            addv=PETSc.InsertMode.ADD)
        border = np.arange(nloc, nloc + ncon, dtype=PETSc.IntType)
        if m == 0:
            C = np.column_stack([c.getArray(readonly=True) for c in self.C])
            own = np.arange(nown, dtype=PETSc.IntType)
            K.setValuesLocalCSR(np.arange(0, ncon * nown + 1, ncon, dtype=PETSc.IntType),
                                np.tile(border, nown), C.ravel(), addv=PETSc.InsertMode.ADD)
            for j in range(ncon):
                K.setValuesLocal(border[j:j + 1], own, C[:, j], addv=PETSc.InsertMode.ADD)
        elif self.comm.getRank() == self.comm.getSize() - 1:
            for j in border:
                K.setValuesLocal(j, j, 1.0, addv=PETSc.InsertMode.ADD)
        K.assemble()
        self._mass.weights = self.forms.mass_weights(m)
        return K

    def spectrum(self, m):
        """Index and the lowest eigenpairs of mode m. Collective.

        Shift-and-invert about sigma finds the eigenvalues nearest sigma, and
        the factorization of H_m - sigma M_m counts those below it: when all of
        these are among the ones found, the ones found are the lowest. The
        first shift is 0, whose inertia is the index. Should eigenvalues below
        sigma be missed, sigma moves below the lowest one found, and on, by
        doubling steps, while more than nev eigenvalues lie below it (an
        assembly and a factorization each, no eigensolve).
        """
        t0 = time.perf_counter()
        solver = self._eigensolver()
        border = len(self.C) if m == 0 else 0   # the constraints' negative eigenvalues
        sigma, step, index = 0.0, None, None
        for _ in range(MAX_SHIFTS):
            # New values on the same pattern: the factorization is numeric only.
            solver.setOperators(self.assemble(m, sigma), self.B)
            solver.setInitialSpace([self._start(m)])
            solver.setUp()
            below = self._factor().getInertia()[0] - border
            index = below if index is None else index
            if step is not None and below > self.nev:
                sigma, step = sigma - step, 2 * step
                continue
            solver.solve()
            values, vectors = self._pairs(solver)
            if not len(values):
                raise RuntimeError(f"m = {m}: no eigenpair converged (shift {sigma:g})")
            values += sigma
            if np.count_nonzero(values < sigma) >= below:
                break
            step = max(values[-1] - values[0], abs(values[0]))
            sigma = values[0] - step
        else:
            raise RuntimeError(f"m = {m}: the {self.nev} lowest eigenvalues were not found with "
                               f"{MAX_SHIFTS} shifts (index {index})")
        values, vectors = values[:self.nev], vectors[:self.nev]
        self._previous = vectors
        return Spectrum(m, index, values, vectors, self._rigid(vectors, m),
                        time.perf_counter() - t0)

    def _eigensolver(self):
        """One Krylov-Schur solver for every m: shift-and-invert about 0 with a
        MUMPS LDL^T, its symbolic factorization shared by all m.

        The pencil is posed as non-Hermitian (GNHEP): Hermitian Lanczos keeps
        its basis B-orthonormal, a mass product per solve, which on 6,124
        nodes cost as much as the solves; Arnoldi in the Euclidean inner
        product needs none and spans the same Krylov space. The eigenvalues
        are real (the pencil is symmetric, B definite on the psi part) and
        equal the Hermitian solver's to 1e-9; `_pairs` M-normalizes the modes.
        """
        from slepc4py import SLEPc
        if self._solver is None:
            solver = self._solver = SLEPc.EPS().create(self.comm)
            solver.setProblemType(SLEPc.EPS.ProblemType.GNHEP)
            # A basis of 2 nev + 2 (SLEPc's default: nev + 15) took ~15% fewer solves.
            solver.setDimensions(self.nev, 2 * self.nev + 2)
            solver.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_REAL)
            solver.setTarget(0.0)
            # `_start` keeps the basis off B's null space, so no purification (an
            # extra inverse iteration per eigenvector, a fifth of the solves). The
            # default tolerance 1e-8 left residuals up to 1.6e-5 ||H psi|| on 2,512
            # nodes; 1e-10 keeps ||H psi - lambda M psi|| <= 3e-9 ||H psi|| for 7
            # more solves over m = 0 ... 3 (49 instead of 42).
            solver.setPurify(False)
            solver.setTolerances(tol=1e-10)
            st = solver.getST()
            st.setType(SLEPc.ST.Type.SINVERT)
            ksp = st.getKSP()
            ksp.setType(PETSc.KSP.Type.PREONLY)
            ksp.getPC().setType(PETSc.PC.Type.CHOLESKY)
            ksp.getPC().setFactorSolverType('mumps')
            solver.setOptionsPrefix(self.prefix)
            solver.setFromOptions()
        return self._solver

    def _start(self, m):
        """The eigensolver's start vector, with no multiplier part and, for
        m = 0, on the constraints' tangent space: the Krylov vectors K^-1 B x
        stay in that space, so the eigenvectors need no purification against
        the null space of the singular B (an extra solve and product each, a
        fifth of them). It is the sum of the modes found for the m before
        (the low modes of neighbouring m look alike: 14% fewer solves over
        m = 0 ... 6), else chi pseudo-random by global number (the same on
        every rank count)."""
        lay = self.layout
        x = self.problem.create_vec()
        if self._previous:
            x.zeroEntries()
            for chi in self._previous:
                x.axpy(1.0 / chi.norm(PETSc.NormType.INFINITY), chi)
        else:
            x.setArray(np.random.default_rng(m).standard_normal(lay.nglobal)
                       [lay.start:lay.start + lay.nowned])
        if m == 0:
            for c, a in zip(self.C, np.linalg.solve(gram(self.C), [c.dot(x) for c in self.C])):
                x.axpy(-a, c)
        v = self.K.createVecRight()
        v.zeroEntries()
        v.getArray()[:lay.nowned] = x.getArray(readonly=True)
        return v

    def _factor(self):
        return self._solver.getST().getKSP().getPC().getFactorMatrix()

    def _pairs(self, solver):
        """Converged eigenvalues of (K, B) ascending and their chi as Vecs,
        M_m-normalized."""
        nown = self.layout.nowned
        y, By = self.K.createVecs()
        pairs = []
        for i in range(solver.getConverged()):
            value = solver.getEigenpair(i, y).real
            self.B.mult(y, By)
            chi = self.problem.create_vec()
            chi.setArray(y.getArray(readonly=True)[:nown] / np.sqrt(y.dot(By)))
            pairs.append((value, chi))
        pairs.sort(key=lambda p: p[0])
        return np.array([p[0] for p in pairs]), [p[1] for p in pairs]

    def field(self, chi, m):
        """psi_h of a distributed chi at this rank's quadrature points. Collective."""
        return self.forms.field(self.problem.local(chi), m)

    def _rigid(self, vectors, m):
        """Per mode, |P psi|^2 / |psi|^2 with P the M_m-orthogonal projection on
        the span of mode m's rigid motions (NaN where it has none). A half
        box's space holds only fields even about its plane: neither the axial
        translation nor the rotation."""
        fields = self.forms.rigid(m)
        if self.half:
            fields = fields[:1] if m == 1 else []
        if not fields:
            return np.full(len(vectors), np.nan)
        mpi, w = self.problem.mpi, kernel.THETA(m) * self.forms.ops.w
        rigid = np.array(fields)
        gram = mpi.allreduce((rigid * w) @ rigid.T)
        out = []
        for chi in vectors:
            psi = self.field(chi, m)
            b = mpi.allreduce(rigid @ (w * psi))
            out.append(b @ np.linalg.solve(gram, b) / mpi.allreduce(np.dot(w * psi, psi)))
        return np.array(out)

    def destroy(self):
        """Free the eigensolver and the mass operator. Collective."""
        if self._solver is not None:
            self._solver.destroy()
            self._solver = None
        if self.B is not None:
            self.B.destroy()
            self.B = None
