"""Azimuthal stability modes of an axisymmetric state: H_m as distributed
PETSc matrices, their index by MUMPS inertia, their lowest eigenpairs by SLEPc.

Per mode m the generalized problem H_m psi = lambda M_m psi is solved, M_m the
L2 mass of the 3D perturbation psi cos(m theta) (`kernels.modes`): lambda is
the second variation of L = E - nu . (c - c0) per unit squared L2 norm. For
m = 0 the perturbation must keep A, V (and M on the full box): the problem is
bordered, [[H_0, C^T], [C, 0]] with B = [[M_0, 0], [0, 0]], whose inertia
counts the constraints' ncon negative eigenvalues besides the tangent space's.
For m >= 1 the constraints drop out: the border rows carry the identity, so
that one matrix layout (the solver's bordered one) serves every m.

One MUMPS LDL^T factorization of H_m - sigma M_m per mode gives both the
inertia (the index: eigenvalues below sigma = 0) and the shift-and-invert
spectral transformation of the eigensolver.
"""
import time
from typing import NamedTuple

import numpy as np
from petsc4py import PETSc

from pfmembrane.kernels import modes as kernel
from pfmembrane.parallel.assembly import Problem

# MUMPS defaults under the prefix: inertia that is right in parallel (no
# ScaLAPACK root), null-pivot detection (which PETSc's MatGetInertia requires
# to count zero pivots; its threshold is ~1e-21 |K|, only exact singularity),
# and QAMD ordering (Debian's MUMPS has no METIS; PORD is slow).
MUMPS_DEFAULTS = {'st_mat_mumps_icntl_13': '1', 'st_mat_mumps_icntl_24': '1',
                  'st_mat_mumps_icntl_7': '6'}
MAX_SHIFTS = 40  # factorizations per m, should the shift have to move far below 0


class Spectrum(NamedTuple):
    """One mode's stability: `index` the number of negative eigenvalues (on
    the constraints' tangent space for m = 0), `eigenvalues` the lowest ones
    ascending, `vectors` their modes as distributed Vecs of chi (psi = r^m chi,
    M_m-normalized: t_m int psi^2 r dr dz = 1), `rigid` for m = 1 the fraction
    of each mode's squared norm in the rigid motions' span
    (`kernels.modes.ModeForms.rigid`; NaN for other m), `time` the seconds
    spent on this m (assembly, factorizations, eigensolve)."""
    m: int
    index: int
    eigenvalues: np.ndarray
    vectors: list
    rigid: np.ndarray
    time: float


class ModeAnalysis:
    """The mode Hessians of one converged state on its grid. Collective.

    `grid` is a `pfmembrane.api.Grid`, `scene` and `eps` those of the state,
    `phi` its nodal values at every node, `nu_area` its tension, `nev` the
    eigenpairs wanted per m. The eigensolver reads its options under `prefix`
    (`-modes_eps_tol`, `-modes_st_mat_mumps_icntl_7`); the MUMPS defaults set
    there are removed by `destroy`. The per-triangle blocks of the operators
    (`kernels.modes.blocks`) are built here, once for every m.
    """

    def __init__(self, grid, scene, eps, phi, nu_area, nev=4, prefix='modes_'):
        d = grid.discrete
        self.comm, self.prefix, self.layout, self.nev = grid.comm, prefix, d.layout, nev
        self._solver = None
        self.problem = Problem(d, eps, scene.k, scene.c0, (scene.area, scene.volume), scene.zc)
        lay = self.layout
        x = self.problem.create_vec()
        x.setArray(np.asarray(phi)[lay.order[lay.start:lay.start + lay.nowned]])
        gA = x.duplicate()
        self.problem.gradients(x, x.duplicate(), gA)
        self.C = [gA, self.problem.grad_V, self.problem.grad_M][:self.problem.ncon]
        self.forms = kernel.ModeForms(d.ops, d.gram, kernel.blocks(d.gram), self.problem.local(x),
                                      eps, scene.k, scene.c0, nu_area, scene.zc)
        self.K = self.problem.bordered_matrix()
        self.B = self.K.duplicate()
        P = d.gram.pattern
        self._pattern = (P.indptr.astype(PETSc.IntType), P.indices.astype(PETSc.IntType))
        self.defaults = []
        db = PETSc.Options()
        for key, value in MUMPS_DEFAULTS.items():
            if not db.hasName(prefix + key):
                db.setValue(prefix + key, value)
                self.defaults.append(prefix + key)

    def assemble(self, m):
        """K = [[H_m, C^T], [C, 0]] (m = 0) or [[H_m, 0], [0, I]], and
        B = [[M_m, 0], [0, 0]]. Collective.

        r^m spans many decades (the mass diagonal 1e-21 ... 0.05 at m = 6 on
        2,512 nodes), but MUMPS' own scaling copes: a diag(M_m)^(-1/2)
        congruence gave the same inertia, no zero pivots either way, and the
        same eigenvalues to every printed digit.
        """
        K, B, lay = self.K, self.B, self.layout
        ncon, nown, nloc = len(self.C), lay.nowned, lay.nlocal
        last = self.comm.getRank() == self.comm.getSize() - 1
        K.zeroEntries()
        B.zeroEntries()
        K.setValuesLocalCSR(*self._pattern, self.forms.hessian(m).data,
                            addv=PETSc.InsertMode.ADD)
        B.setValuesLocalCSR(*self._pattern, self.forms.mass(m).data, addv=PETSc.InsertMode.ADD)
        border = np.arange(nloc, nloc + ncon, dtype=PETSc.IntType)
        if m == 0:
            C = np.column_stack([c.getArray(readonly=True) for c in self.C])
            own = np.arange(nown, dtype=PETSc.IntType)
            K.setValuesLocalCSR(np.arange(0, ncon * nown + 1, ncon, dtype=PETSc.IntType),
                                np.tile(border, nown), C.ravel(), addv=PETSc.InsertMode.ADD)
            for j in range(ncon):
                K.setValuesLocal(border[j:j + 1], own, C[:, j], addv=PETSc.InsertMode.ADD)
        elif last:
            for j in border:
                K.setValuesLocal(j, j, 1.0, addv=PETSc.InsertMode.ADD)
        K.assemble()
        B.assemble()
        return K, B

    def spectrum(self, m):
        """Index and the lowest eigenpairs of mode m. Collective.

        Shift-and-invert finds the eigenvalues nearest the shift sigma, and the
        factorization of K - sigma B counts those below it: when all of these
        are among the ones found, the ones found are the lowest. The first
        shift is 0, whose inertia is the index. Should eigenvalues below sigma
        be missed, sigma moves below the lowest one found, and on, by doubling
        steps, while more than nev eigenvalues lie below it (a factorization
        each, no eigensolve).
        """
        t0 = time.perf_counter()
        K, B = self.assemble(m)
        solver = self._eigensolver()
        border = len(self.C) if m == 0 else 0   # the constraints' negative eigenvalues
        sigma, step, index = 0.0, None, None
        for _ in range(MAX_SHIFTS):
            # New values on the same pattern: the factorization is numeric only.
            solver.setOperators(K, B)
            solver.setTarget(sigma)
            solver.setUp()
            below = self._factor().getInertia()[0] - border
            index = below if index is None else index
            if step is not None and below > self.nev:
                sigma, step = sigma - step, 2 * step
                continue
            solver.solve()
            values, vectors = self._pairs(solver, K)
            if not len(values):
                raise RuntimeError(f"m = {m}: no eigenpair converged (shift {sigma:g})")
            if np.count_nonzero(values < sigma) >= below:
                break
            step = max(values[-1] - values[0], abs(values[0]))
            sigma = values[0] - step
        else:
            raise RuntimeError(f"m = {m}: the {self.nev} lowest eigenvalues were not found with "
                               f"{MAX_SHIFTS} shifts (index {index})")
        values, vectors = values[:self.nev], vectors[:self.nev]
        rigid = self._rigid(vectors) if m == 1 else np.full(len(values), np.nan)
        return Spectrum(m, index, values, vectors, rigid, time.perf_counter() - t0)

    def _eigensolver(self):
        """One Krylov-Schur solver for every m: GHEP, shift-and-invert with a
        MUMPS LDL^T, its symbolic factorization shared by all m (one pattern)."""
        from slepc4py import SLEPc
        if self._solver is None:
            solver = self._solver = SLEPc.EPS().create(self.comm)
            solver.setProblemType(SLEPc.EPS.ProblemType.GHEP)
            # A basis of 2 nev + 2 (SLEPc's default: nev + 15) takes ~15% fewer solves.
            solver.setDimensions(self.nev, 2 * self.nev + 2)
            solver.setWhichEigenpairs(SLEPc.EPS.Which.TARGET_REAL)
            st = solver.getST()
            st.setType(SLEPc.ST.Type.SINVERT)
            st.setMatStructure(PETSc.Mat.Structure.SAME_NONZERO_PATTERN)  # B on K's pattern
            ksp = st.getKSP()
            ksp.setType(PETSc.KSP.Type.PREONLY)
            ksp.getPC().setType(PETSc.PC.Type.CHOLESKY)
            ksp.getPC().setFactorSolverType('mumps')
            solver.setOptionsPrefix(self.prefix)
            solver.setFromOptions()
        return self._solver

    def _factor(self):
        return self._solver.getST().getKSP().getPC().getFactorMatrix()

    def _pairs(self, solver, K):
        """Converged eigenvalues ascending and their chi as Vecs."""
        nown = self.layout.nowned
        y = K.createVecRight()
        pairs = []
        for i in range(solver.getConverged()):
            value = solver.getEigenpair(i, y).real
            chi = self.problem.create_vec()
            chi.setArray(y.getArray(readonly=True)[:nown])
            pairs.append((value, chi))
        pairs.sort(key=lambda p: p[0])
        return np.array([p[0] for p in pairs]), [p[1] for p in pairs]

    def field(self, chi, m):
        """psi_h of a distributed chi at this rank's quadrature points. Collective."""
        return self.forms.field(self.problem.local(chi), m)

    def _rigid(self, vectors):
        """Per m = 1 mode, |P psi|^2 / |psi|^2 with P the M_1-orthogonal
        projection on the rigid motions' span."""
        mpi, w = self.problem.mpi, kernel.THETA(1) * self.forms.ops.w
        rigid = np.array(self.forms.rigid())
        gram = mpi.allreduce((rigid * w) @ rigid.T)
        out = []
        for chi in vectors:
            psi = self.field(chi, 1)
            b = mpi.allreduce(rigid @ (w * psi))
            out.append(b @ np.linalg.solve(gram, b) / mpi.allreduce(np.dot(w * psi, psi)))
        return np.array(out)

    def nodal(self, chi):
        """chi at every node (0 on the Dirichlet nodes), on every rank. Collective."""
        values = self.layout.gather(chi)
        values = self.comm.tompi4py().bcast(values, root=0)
        out = np.zeros(len(self.layout.number))
        out[self.layout.order] = values
        return out

    def destroy(self):
        """Free the eigensolver and the mass matrix, and remove the MUMPS
        defaults from the database. Collective."""
        if self._solver is not None:
            self._solver.destroy()
        self.B.destroy()
        db = PETSc.Options()
        for key in self.defaults:
            db.delValue(key)
