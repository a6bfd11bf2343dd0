"""Stage 1: augmented Lagrangian; stage 2: Newton on the bordered (Phi, nu) system.

Convention (the paper's, restated in the README's model section):
L = E - nu . (c - c0), c = (A, V, M), or c = (A, V) on a half box; the
multiplier update is nu <- nu - (c - c0) / mu. nu_A is the membrane tension,
nu_V the pressure difference.
"""
import ctypes
import time

import numpy as np
from petsc4py import PETSc

from pfmembrane.parallel.faults import poll
from pfmembrane.parallel.petsc import MUMPS_LDLT, libpetsc


SHIFT_GROWTH = 8.0
# A restart's first augmented-Lagrangian pass ends when a Newton step would lower
# L_A by less than RESTART_DECREMENT of |L_A| (soft modes leave |grad| small
# far from the minimizer), or at once where |grad L| < RESTART_GTOL |grad E|.
RESTART_DECREMENT = 1e-9
RESTART_GTOL = 1e-6


# Where the Jacobian is an action (harmonics), GMRES solves each Newton step to
# KRYLOV_RTOL. Near a bifurcation Newton needs the soft mode, which GMRES resolves
# last: a looser forcing (1e-2, 1e-3, or Eisenstat-Walker's) took more Newton steps on
# the three-fold scene of runs/harmonics/cost.py, 1e-6 the same as 1e-10.
KRYLOV_RTOL = 1e-6
KRYLOV_MAX_IT = 500
# GMRES's restart there: with the default 30 it stagnated on a prolate across the axis
# with m up to 12 (runs/harmonics/across.py), where the theta-averaged model is poor.
KRYLOV_RESTART = 200
# Stage-2 Newton steps whose GMRES may stop short of KRYLOV_RTOL before SNES gives up:
# near the answer the action's rounding floor can lie above rtol |F|, and GMRES's last
# iterate is still a good direction (SNES's own test judges the step).
KRYLOV_FAILURES = 5
# The energy path (-pf_path) puts each iterate on the constraints to this residual,
# relative to their scales, in at most this many Gauss-Newton steps.
PROJECT_RTOL = 1e-12
PROJECT_MAX_IT = 20


def gram(vectors):
    """The Gram matrix of the Vecs `vectors` (the constraints' gradients). Collective."""
    return np.array([[a.dot(b) for b in vectors] for a in vectors])


class SolveError(Exception):
    """A stage that did not converge; carries the reason and a remedy."""


def stage1_penalty(settings):
    """The initial penalty mu of the augmented Lagrangian."""
    if settings.mu > 0:
        return settings.mu
    return 1e-5 if settings.stage1 == 'newton' else 1e-4


class Solver:
    """Drives both stages on one Problem. Collective.

    `settings` holds the application's solver options (`io.options.Settings`);
    the PETSc objects read theirs under the prefix of `options` (a
    `parallel.petsc.Options` scope) + 'stage1_' and 'stage2_', and the
    defaults the solver gives PETSc (MUMPS controls) go into that scope. `x`
    is the distributed Vec of free nodal values, updated in place.
    """

    def __init__(self, problem, settings, options, print_fn=PETSc.Sys.Print):
        self.P, self.p = problem, settings
        self.options, self.prefix = options, options.prefix
        self.print = print_fn
        self.gE, self.gA = problem.create_vec(), problem.create_vec()
        self.ncon = problem.ncon
        self.C = problem.constraint_gradients(self.gA)
        area, volume = problem.targets[:2]
        radius = np.sqrt(area / (4.0 * np.pi))
        # residuals relative to these: the moments' volume times radius, the phase an angle
        self.scale = np.array([area, volume] + [1.0 if m == 'Theta' else volume * radius
                                                for m in problem.moments])
        self.nu = np.zeros(self.ncon)
        self._shift = 0.0  # Hessian shift that last made a stage-1 Newton step a descent
        self._model_its = None  # Krylov iterations of the first solve on the model (`_keep`)
        self.factorizations = 0
        self._ksps = {}  # direct solvers by options prefix (`direct_ksp`)
        self.mpi = problem.mpi
        self.stats = {}
        self.history = []  # E at every iteration of both stages
        self.path = []  # ... with -pf_path, E of each iterate put on the constraints
        self._projection = None  # work Vecs of `project`

    # -- helpers ---------------------------------------------------------------
    def evaluate(self, x):
        """Values (E, A, V, M), constraint residual c - c0; fills gE, gA."""
        poll(self.mpi)  # every iteration of both stages passes here: leave together on a signal
        vals = self.P.gradients(x, self.gE, self.gA)
        return vals, self.P.constraints(vals) - self.P.targets

    def combine(self, out, lam):
        """out = gE - sum lam_i C_i (the gradient of a Lagrangian)."""
        self.gE.copy(out)
        for li, ci in zip(lam, self.C):
            out.axpy(-li, ci)
        return out

    def _keep(self, its):
        """Whether the next Newton step keeps the factored model of an action
        (`krylov`), given the Krylov iterations `its` of the last solve: yes
        until a solve needs more than -pf_refresh times the iterations of the
        first solve on it (the model, diag(H_m) at the theta-averaged state,
        only preconditions the exact action, and its assembly and factorization
        cost several GMRES iterations); no at the start of a stage
        (`_model_its` None) and after a shift."""
        if not (self.P.krylov and self.p.refresh > 0 and self._model_its is not None):
            self._model_its = 0
            return False
        if self._model_its == 0:  # the first solve on a fresh model
            self._model_its = max(its, 1)
            return True
        if its <= self.p.refresh * self._model_its:
            return True
        self._model_its = 0
        return False

    def least_squares_multipliers(self):
        """nu minimizing |grad E - C^T nu|: keeps the initial guess on its branch."""
        rhs = np.array([c.dot(self.gE) for c in self.C])
        return np.linalg.solve(gram(self.C), rhs)

    def project(self, x):
        """E at x put on the constraints c = c0, x itself unchanged: Gauss-Newton
        steps y -= C^T (C C^T)^-1 (c - c0) along the constraints' gradients C
        at y, the least change that meets them to first order (A alone is
        nonlinear). On work Vecs of its own, so that the solver's gradients stay
        those of x. Collective."""
        P = self.P
        if self._projection is None:
            self._projection = (P.create_vec(), P.create_vec(), P.create_vec())
        gE, gA, y = self._projection
        x.copy(y)
        C = P.constraint_gradients(gA)
        for _ in range(PROJECT_MAX_IT):
            vals = P.gradients(y, gE, gA)
            res = P.constraints(vals) - P.targets
            if np.all(np.abs(res) <= PROJECT_RTOL * self.scale):
                return vals[0]
            for step, c in zip(np.linalg.solve(gram(C), res), C):
                y.axpy(-step, c)
        raise SolveError(f"an iterate did not reach the constraints in {PROJECT_MAX_IT} "
                         f"Gauss-Newton steps (residual {np.abs(res / self.scale).max():.2e})")

    def row(self, stage, it, x, vals, res, gnorm):
        """Record iterate `it` of `stage` (E, and with -pf_path E on the
        constraints); print its row under -pf_monitor."""
        self.history.append(vals[0])
        if self.p.path:
            self.path.append(self.project(x))
        if self.p.monitor:
            rel = np.abs(res) / self.scale
            moment = ''.join(f"r{m} {r:.2e} " for m, r in zip(self.P.moments, rel[2:]))
            self.print(f"  {stage} {it:3d} E {vals[0]:.10f} |g| {gnorm:.3e} "
                       f"rA {rel[0]:.2e} rV {rel[1]:.2e} {moment}"
                       f"nuA {self.nu[0]:.5g} nuV {self.nu[1]:.5g}")

    # -- stage 1 ---------------------------------------------------------------
    def stage1(self, x, nu=None):
        """Augmented Lagrangian to the coarse tolerance -pf_stage1_rtol.

        From scratch the multipliers are least-squares ones and a short warm-up
        pass precedes the first update. From a solved state's multipliers `nu`
        (a restart) the first pass instead converges (RESTART_DECREMENT): off
        equilibrium the least-squares fit is far off (nu_A ~ 7e3 for 9), and an
        update after an unconverged pass moves nu by residual / mu, 1e5 times
        the residual.
        """
        t0 = time.perf_counter()
        mu = stage1_penalty(self.p)
        vals, res = self.evaluate(x)
        grad_L = x.duplicate()
        gtol, decrement = None, None
        if nu is None:
            self.nu = self.least_squares_multipliers()
        else:
            self.nu = np.asarray(nu, dtype=float)
            gtol, decrement = RESTART_GTOL * self.gE.norm(), RESTART_DECREMENT
        inner = self._tao if self.p.stage1 == 'tao' else self._newton
        iters = 0
        for outer in range(1, self.p.stage1_max_it + 1):
            iters += inner(x, mu, gtol, decrement)
            decrement = None
            vals, res = self.evaluate(x)
            rel = np.abs(res) / self.scale
            self.nu = self.nu - res / mu
            g = self.combine(grad_L, self.nu).norm()
            # after the first pass (a warm-up, or a restart's converged one) the
            # tolerance follows |grad L|
            gtol = 0.1 * g if outer == 1 else min(gtol, 0.1 * g)
            self.row('AL', outer, x, vals, res, g)
            if rel.max() < self.p.stage1_rtol:
                break
        else:
            raise SolveError(f"stage 1 did not reach constraint residual {self.p.stage1_rtol:g} "
                             f"in {self.p.stage1_max_it} outer iterations (last {rel.max():.2e}); "
                             "try a stronger penalty (-pf_mu smaller) or a finer grid")
        self.stats['stage1'] = dict(outer=outer, inner=iters, time=time.perf_counter() - t0,
                                    energy=vals[0], residual=rel.max())
        return vals, res

    def _augmented(self, vals, res, mu):
        return vals[0] - np.dot(self.nu, res) + np.dot(res, res) / (2 * mu)

    def _newton(self, x, mu, gtol, decrement=None, max_it=50):
        """Newton with line search on L_A to |grad| <= gtol, or to an unshifted
        step's predicted decrease <= decrement |L_A|; the step solves the
        bordered system [[H, -C^T], [-C, -mu I]] whose inertia has exactly ncon
        negative eigenvalues iff Hess L_A = H + C^T C / mu is positive definite."""
        P = self.P
        ksp = self.direct_ksp('stage1_')
        K = P.bordered_matrix()
        rhs, sol = K.createVecs()
        g, d, xt = x.duplicate(), x.duplicate(), x.duplicate()
        nl = P.layout.nowned
        self._model_its = None
        for it in range(max_it):
            vals, res = self.evaluate(x)
            lam = self.nu - res / mu
            self.combine(g, lam)
            gnorm = g.norm()
            self.row('newton', it, x, vals, res, gnorm)
            if gtol is not None and gnorm <= gtol:
                return it
            La = self._augmented(vals, res, mu)
            kept = not self._shift and self._keep(ksp.getIterationNumber())
            P.assemble_bordered(x, lam[0], self.C, -mu, keep=kept)
            # Hess L_A may be indefinite away from the minimizer: shift it (Nocedal-Wright
            # 3.4), first by a quarter of the shift that last sufficed, then by factors
            # SHIFT_GROWTH from a tenth of the mean diagonal. The factorization's inertia
            # says whether a shift suffices; the matrix is shifted in place, not rebuilt.
            scale = self._mean_diagonal(K)
            applied = self._shift
            if applied:
                P.shift_hessian(applied)
            while True:
                ksp.setOperators(P.jacobian_operator(), K)
                rhs.zeroEntries()
                rhs.getArray()[:nl] = -g.getArray(readonly=True)
                ksp.solve(rhs, sol)
                self.factorizations += not kept
                kept = False  # a shift changes the model
                # the factored model's inertia is not the exact Hessian's: with an
                # action (krylov) only the descent test stands
                nneg = None if P.krylov else self.negative_pivots(ksp)
                d.setArray(sol.getArray(readonly=True)[:nl])
                slope = g.dot(d)
                if (nneg is None or nneg == self.ncon) and slope < 0:
                    break
                if nneg is None and not applied:
                    # No inertia (an action): the failed step says how far to shift. It
                    # solves Hess L_A d = -g, so d^T Hess L_A d = -slope <= 0, and the
                    # lowest eigenvalue lies below -slope / |d|^2: shift by twice that.
                    # A tenth of the mean diagonal, far more than a saddle's small
                    # negative curvature, makes steps too short to leave the saddle.
                    shift = max(2 * slope / d.dot(d), 1e-12 * scale)
                else:
                    shift = SHIFT_GROWTH * applied if applied else 0.1 * scale
                P.shift_hessian(shift - applied)
                applied = shift
            if applied:
                self._model_its = None  # a shifted model is rebuilt at the next step
            if decrement is not None and not applied and -slope <= 2 * decrement * abs(La):
                return it
            self._shift = applied / 4 if applied > 1e-3 * scale else 0.0
            t = 1.0
            while True:
                x.copy(xt)
                xt.axpy(t, d)
                v2 = P.values(xt)
                r2 = P.constraints(v2) - P.targets
                if self._augmented(v2, r2, mu) <= La + 1e-4 * t * slope or t < 1e-8:
                    break
                t *= 0.5
            xt.copy(x)
            if gtol is None and it >= 2:
                return it + 1
        return max_it

    @staticmethod
    def _mean_diagonal(K):
        return K.getDiagonal().norm(PETSc.NormType.NORM_1) / K.getSize()[0]

    def negative_pivots(self, ksp):
        pc = ksp.getPC()
        try:
            if pc.getType() == PETSc.PC.Type.REDUNDANT:
                return redundant_negative_pivots(pc)
            return pc.getFactorMatrix().getInertia()[0]
        except PETSc.Error:
            return None

    def _tao(self, x, mu, gtol, decrement=None):
        """One inner minimization of L_A with a TAO gradient-based solver
        (to gtol; a Newton decrement is not available to it)."""
        P = self.P
        tao = getattr(self, '_tao_obj', None)
        if tao is None:
            tao = self._tao_obj = PETSc.TAO().create(P.comm)
            tao.setOptionsPrefix(self.prefix + 'stage1_')
            tao.setType(PETSc.TAO.Type.BQNLS)
            tao.setMaximumIterations(500)
            tao.setFromOptions()
        g = x.duplicate()

        def objgrad(tao, xx, G):
            vals, res = self.evaluate(xx)
            self.combine(G, self.nu - res / mu)
            return self._augmented(vals, res, mu)

        tao.setObjectiveGradient(objgrad, g)
        tao.setTolerances(gatol=gtol if gtol is not None else 1e-2, grtol=0.0, gttol=0.0)
        tao.solve(x)
        return tao.getIterationNumber()

    # -- stage 2 ---------------------------------------------------------------
    def stage2_first(self, x, solved_nu=None):
        """Stage 2 straight from x and the multipliers (a restart near its answer);
        should it fail, both stages again from the same start, stage 1 from
        `solved_nu` as in `stage1`."""
        x0, nu0 = x.copy(), self.nu.copy()
        try:
            return self.stage2(x)
        except SolveError as e:
            if self.p.summary or self.p.monitor:
                self.print(f"stage2: {e}; both stages from the restart instead")
        x0.copy(x)
        self.nu = nu0
        self.stage1(x, solved_nu)
        return self.stage2(x)

    def stage2(self, x):
        """Newton (SNES) on (Phi, nu): residual [grad E - C^T nu; -(c - c0)]."""
        t0 = time.perf_counter()
        P = self.P
        K = P.bordered_matrix()
        X, F = K.createVecs()
        nl = P.layout.nowned
        last = P.comm.getRank() == P.comm.getSize() - 1
        X.getArray()[:nl] = x.getArray(readonly=True)
        if last:
            X.getArray()[nl:] = self.nu
        g, xx = x.duplicate(), x.duplicate()

        def unpack(XX):
            xx.setArray(XX.getArray(readonly=True)[:nl])
            nu = XX.getArray(readonly=True)[nl:] if last else None
            return np.asarray(self.mpi.bcast(None if nu is None else nu.copy(),
                                             root=P.comm.getSize() - 1))

        last_vals = [None]

        def residual(snes, XX, FF):
            nu = unpack(XX)
            vals, res = self.evaluate(xx)
            last_vals[0] = vals
            self.combine(g, nu)
            FF.getArray()[:nl] = g.getArray(readonly=True)
            if last:
                FF.getArray()[nl:] = -res

        def jacobian(snes, XX, J, Pm):
            nu = unpack(XX)
            self.evaluate(xx)  # grad A at this X: the last residual may have been elsewhere
            keep = self._keep(snes.getKSP().getIterationNumber())
            self.factorizations += not keep
            P.assemble_bordered(xx, nu[0], self.C, 0.0, keep=keep)

        snes = PETSc.SNES().create(P.comm)
        self._model_its = None
        snes.setOptionsPrefix(self.prefix + 'stage2_')
        snes.setFunction(residual, F)
        snes.setJacobian(jacobian, P.jacobian_operator(), K)
        snes.setTolerances(rtol=self.p.stage2_rtol, atol=1e-12, max_it=50)
        # Full Newton steps: stage 2 starts where stage 1 has converged, and there
        # |F| is a poor merit function. On the 24,597-node discocyte at eps 0.007
        # a full step takes |F| from 4.4e-6 to 9.5e-5 and the next to 3e-11, while
        # backtracking (bt) crawled at 2-10% steps for 50 iterations.
        self.options.default('stage2_snes_linesearch_type', 'basic')
        if P.krylov:
            self.options.default('stage2_snes_max_linear_solve_fail', KRYLOV_FAILURES)
        self._configure_direct(snes.getKSP(), 'stage2_')
        snes.setFromOptions()
        self._redundant_defaults(snes.getKSP(), 'stage2_')
        snes.setConvergenceHistory()
        # SNES monitors after the residual at the new iterate
        def monitor(snes, it, fnorm):
            self.history.append(last_vals[0][0])
            if self.p.path:
                unpack(snes.getSolution())
                self.path.append(self.project(xx))

        snes.setMonitor(monitor)
        X0 = X.copy()
        snes.solve(None, X)
        reason = snes.getConvergedReason()
        history = snes.getConvergenceHistory()[0]
        if reason <= 0 and len(history) > 1 and not history[-1] < history[0]:
            X0.copy(X)  # a failed solve keeps (and checkpoints) the better of start and end
        self.nu = unpack(X)
        x.setArray(xx.getArray(readonly=True))
        vals, res = self.evaluate(x)
        rel = np.abs(res) / self.scale
        self.stats['stage2'] = dict(iterations=snes.getIterationNumber(), reason=reason,
                                    linear_iterations=snes.getLinearSolveIterations(),
                                    time=time.perf_counter() - t0, energy=vals[0],
                                    residual=rel.max())
        snes.destroy()
        if reason <= 0:
            raise SolveError(f"stage 2 Newton did not converge (SNES reason {reason}); "
                             "try a tighter stage 1 (-pf_stage1_rtol) or a finer grid")
        return vals, res

    def destroy(self):
        """Free the PETSc objects kept between iterations."""
        for ksp in self._ksps.values():
            ksp.destroy()
        self._ksps.clear()
        tao = self.__dict__.pop('_tao_obj', None)
        if tao is not None:
            tao.destroy()
        for v in self._projection or ():
            v.destroy()

    # -- linear solvers --------------------------------------------------------
    def _configure_direct(self, ksp, stage):
        """Defaults: a MUMPS LDL^T factorization (the bordered matrices are
        symmetric indefinite, and LDL^T takes about half the work of LU)
        with AMD-type ordering; options override."""
        ksp.setOptionsPrefix(self.prefix + stage)
        if self.P.krylov:
            # the operator is the exact Hessian's action, the factored matrix its
            # block-diagonal model: GMRES to a tight tolerance keeps Newton quadratic
            ksp.setType(PETSc.KSP.Type.GMRES)
            ksp.setGMRESRestart(KRYLOV_RESTART)
            ksp.setTolerances(rtol=KRYLOV_RTOL, max_it=KRYLOV_MAX_IT)
        else:
            ksp.setType(PETSc.KSP.Type.PREONLY)
        pc = ksp.getPC()
        pc.setType(PETSc.PC.Type.CHOLESKY)
        pc.setFactorSolverType('mumps')
        self.options.mumps(stage)

    def _redundant_defaults(self, ksp, stage):
        """The same LDL^T inside a PCREDUNDANT (`-stage1_pc_type redundant`): every rank
        factors the whole matrix with sequential MUMPS, and its inertia still gives the
        stage-1 shifts and the index."""
        if ksp.getPC().getType() != PETSc.PC.Type.REDUNDANT:
            return
        # sequential MUMPS: its inertia needs no parallel setting (icntl 13)
        for name, value in (('pc_type', 'cholesky'), ('pc_factor_mat_solver_type', 'mumps'),
                            *((k, v) for k, v in MUMPS_LDLT.items() if k != 'mat_mumps_icntl_13')):
            self.options.default(stage + 'redundant_' + name, value)

    def direct_ksp(self, stage):
        """One LDL^T (MUMPS Cholesky) solver under the `stage` prefix, kept for
        every later factorization of the same pattern (numeric only)."""
        if stage not in self._ksps:
            ksp = self._ksps[stage] = PETSc.KSP().create(self.P.comm)
            self._configure_direct(ksp, stage)
            ksp.setFromOptions()
            self._redundant_defaults(ksp, stage)
        return self._ksps[stage]



def redundant_negative_pivots(pc):
    """The negative pivots of the factorization inside a PCREDUNDANT, through the C API
    that petsc4py does not wrap (SLEPc's spectrum slicing reads it the same way)."""
    lib = libpetsc()
    inner, inner_pc, factor = ctypes.c_void_p(), ctypes.c_void_p(), ctypes.c_void_p()
    nneg = np.zeros(1, dtype=PETSc.IntType)
    for call, args in ((lib.PCRedundantGetKSP, (ctypes.c_void_p(pc.handle), ctypes.byref(inner))),
                       (lib.KSPGetPC, (inner, ctypes.byref(inner_pc))),
                       (lib.PCFactorGetMatrix, (inner_pc, ctypes.byref(factor))),
                       (lib.MatGetInertia, (factor, nneg.ctypes.data_as(ctypes.c_void_p),
                                            None, None))):
        code = call(*args)
        if code:
            raise PETSc.Error(code)
    return int(nneg[0])
