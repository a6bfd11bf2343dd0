"""One problem: a scene at one width eps on one grid, with the solvers that
read the options of its prefix (in the manner of DOLFINx's NonlinearProblem).

A `Problem` refuses an empty prefix, pushes the options it is given under
its prefix (`parallel.petsc.Options`), builds its TAO/SNES/KSP/SLEPc objects
from them, and on `close` destroys them and leaves the options database as
it found it. Solves, tangents, continuation and mode analyses all go
through one. Besides the two stages it offers what a continuation needs:
the residual F(x, nu; p) of the bordered system, its Jacobian factored, and
the parameter derivative F_p.
"""
import itertools

import numpy as np

from pfmembrane.io.options import UsageError, read_settings, targets
from pfmembrane.parallel.assembly import Assembly
from pfmembrane.parallel.faults import Interrupted, OutOfTime
from pfmembrane.parallel.petsc import Options, start
from pfmembrane.parallel.solver import PROJECT_RTOL, SolveError, Solver

# Scene parameters a branch can follow (`at`).
PARAMETERS = ('reduced_volume', 'c0', 'radius')
# Relative parameter step of the central difference F_p.
DP = 1e-4


class Problem:
    """The scene `scene` at `eps` on `grid` (a `pfmembrane.Grid`), its solver
    options `options` (names without the dash) under `prefix`. Collective on
    the grid's communicator; a context manager that closes it."""

    def __init__(self, grid, scene, eps, prefix, options=None):
        self.options = Options(prefix, options)
        self.prefix = prefix
        try:
            PETSc = start()
            self.settings = read_settings(PETSc.Options(), prefix)
            self.grid, self.scene, self.eps = grid, scene, eps
            self.assembly = assembly(grid.discrete, eps, scene, self.settings.hessian == 'coupled')
            self.solver = Solver(self.assembly, self.settings, self.options)
        except BaseException:
            self.options.close()
            raise
        self.layout = self.assembly.layout  # the unknowns' numbering (with harmonics, interleaved)
        self.comm, self.mpi = grid.comm, grid.comm.tompi4py()
        self.ncon = self.assembly.ncon
        self._analyses = []
        self._work = None

    # -- state -----------------------------------------------------------------
    @property
    def nu(self):
        """The multipliers (nu_A, nu_V[, nu_M][, nu_X]) of the current state."""
        return self.solver.nu

    @nu.setter
    def nu(self, value):
        self.solver.nu = np.asarray(value, dtype=float)

    def vec(self, phi):
        """The distributed Vec of the free values of nodal `phi` (every node)."""
        return self.assembly.layout.vec(phi)

    def nodal(self, x, fill=-1.0):
        """Nodal phi at every node on every rank (`fill` on the Dirichlet nodes)."""
        return self.assembly.layout.nodal(x, fill)

    # -- the two stages --------------------------------------------------------
    def solve(self, x, nu0=None, solved=False):
        """Stage 1 then stage 2 (or stage 2 first with -pf_stage1 none), each a
        PETSc log stage, with a one-line summary each under -pf_summary. A
        solved start's multipliers `nu0` start stage 1 better than a
        least-squares fit; stage 2 first starts from the start's multipliers,
        solved or not. Returns (converged, message, status, (E, A, V, M), the
        log stages); a stage that fails or a signal ends it unconverged."""
        PETSc = start()
        solver, settings = self.solver, self.settings
        if nu0 is not None and len(nu0) < self.ncon:
            # a start without the moment across the axis (axisymmetric, or sharp): that
            # multiplier vanishes at every equilibrium, E, A and V being invariant under
            # the translation it pins
            nu0 = np.concatenate([nu0, np.zeros(self.ncon - len(nu0))])
        solved_nu = nu0 if solved else None
        self.assembly.hold(x)
        stages = [('pfStage1', lambda v: solver.stage1(v, solved_nu)),
                  ('pfStage2', solver.stage2)]
        if settings.stage1 == 'none':
            stages = [('pfStage2', lambda v: solver.stage2_first(v, solved_nu))]
            if nu0 is None:
                solver.evaluate(x)
                solver.nu = solver.least_squares_multipliers()
            else:
                solver.nu = np.asarray(nu0, dtype=float)
        logged = []
        try:
            for name, fn in stages:
                stage = PETSc.Log.Stage(name)
                logged.append(stage)
                stage.push()
                try:
                    vals, _ = fn(x)
                finally:
                    stage.pop()
                s = solver.stats[name[2:].lower()]
                if settings.summary:
                    PETSc.Sys.Print(
                        f"{name[2:].lower()}: {s.get('outer', s.get('iterations'))} its"
                        f"{' (' + str(s['inner']) + ' inner)' if 'inner' in s else ''}, "
                        f"E {s['energy']:.8f}, constraint residual {s['residual']:.2e}, "
                        f"max|phi| {self.assembly.max_abs_phi(x):.4f}, {s['time']:.2f} s",
                        comm=self.comm)
        except (SolveError, Interrupted, OutOfTime) as e:
            status = getattr(e, 'status', 1)
            return (False, str(e), status, self.assembly.gradients(x, solver.gE, solver.gA),
                    logged)
        if settings.summary and settings.path:
            PETSc.Sys.Print(path_line(solver.path), comm=self.comm)
        return True, '', 0, vals, logged

    # -- what a continuation needs ---------------------------------------------
    # A branch is followed in a scene parameter p that `at` sets: the targets c0
    # and C0. F is quadratic in C0 (grad E is linear in W, W affine in C0), so F_p
    # by central differences is exact but for rounding; where C0 stays, only the
    # constraint rows -(c - c0) move.
    def at(self, parameter, value):
        """Put the problem at `value` of a scene parameter (`PARAMETERS`): its
        targets and C0. Not a Scene: a corrector's iterate may pass where no
        scene is (v > 1)."""
        p = {name: getattr(self.scene, name) for name in PARAMETERS}
        p[parameter] = value
        self.assembly.targets[:2] = targets(p['radius'], p['reduced_volume'])
        self.assembly.forms.c0 = p['c0']

    def bordered_vec(self):
        """A Vec of the bordered layout (x, nu), the last rank holding nu."""
        return self.assembly.bordered_matrix().createVecLeft()

    def residual(self, x, out):
        """out = F(x, nu) = [grad E - C^T nu; -(c - c0)] in the bordered layout."""
        P, solver = self.assembly, self.solver
        nl = P.layout.nowned
        if self._work is None:
            self._work = P.create_vec()
        _, res = solver.evaluate(x)
        out.getArray()[:nl] = solver.combine(self._work, solver.nu).getArray(readonly=True)
        if P.comm.getRank() == P.comm.getSize() - 1:
            out.getArray()[nl:] = -res
        return out

    def parameter_derivative(self, x, parameter, p, out):
        """out = dF/dp at (x, nu, p), by central differences; leaves the problem at p.
        A parameter that moves only the targets (v, R) costs no evaluation of F."""
        P = self.assembly
        h = DP * max(1.0, abs(p))
        self.at(parameter, p + h)
        up, c0_up = P.targets.copy(), P.forms.c0
        self.at(parameter, p - h)
        if P.forms.c0 == c0_up:  # F_p = [0; dc0/dp]
            out.zeroEntries()
            if P.comm.getRank() == P.comm.getSize() - 1:
                out.getArray()[P.layout.nowned:] = (up - P.targets) * (0.5 / h)
        else:
            self.residual(x, out)
            self.at(parameter, p + h)
            out.axpy(-1.0, self.residual(x, out.duplicate()))
            out.scale(-0.5 / h)
        self.at(parameter, p)
        return out

    def split(self, X):
        """(x part Vec, nu part on every rank) of a bordered-layout Vec."""
        P = self.assembly
        nl, last = P.layout.nowned, P.comm.getRank() == P.comm.getSize() - 1
        x = P.create_vec()
        x.setArray(X.getArray(readonly=True)[:nl])
        nu = X.getArray(readonly=True)[nl:].copy() if last else None
        return x, np.asarray(self.mpi.bcast(nu, root=P.comm.getSize() - 1))

    def jacobian(self, x):
        """The stage-2 direct solver with the Jacobian at (x, nu) as its operator
        (factored at its next solve)."""
        solver = self.solver
        K = self.assembly.bordered_matrix()
        solver.evaluate(x)
        self.assembly.assemble_bordered(x, solver.nu[0], solver.C, 0.0)
        ksp = solver.direct_ksp('stage2_')
        ksp.setOperators(self.assembly.jacobian_operator(), K)
        solver.factorizations += 1
        return ksp

    def negative_pivots(self, ksp):
        """The negative pivots of the factorization in `ksp` (None without inertia)."""
        return self.solver.negative_pivots(ksp)

    # -- leaving an equilibrium -------------------------------------------------
    def lagrangian(self, x, nu):
        """L = E - nu . (c - c0) at x. Collective."""
        P = self.assembly
        vals = P.values(x)
        return vals[0] - np.dot(nu, P.constraints(vals) - P.targets)

    def slaved(self, x0, d):
        """The second-order term (w, dnu) of the path x0 + t d + t^2 w, nu + t^2
        dnu out of the equilibrium (x0, nu) (the problem's multipliers) along
        the critical direction d: the rest of the unknowns at their equilibrium
        given t, to second order (the centre manifold's Taylor term). It solves
        J [w; dnu] = -F''[d, d] / 2, J the bordered Jacobian at x0 and F'' by
        the central second difference of F with step d. J w is solvable where
        F''[d, d] has no part along d, which holds for a critical mode of one
        harmonic m > 0: F''[d, d] lies in the harmonics 0 and 2m. Collective."""
        F0, up, down = self.bordered_vec(), self.bordered_vec(), self.bordered_vec()
        x = x0.copy()
        self.residual(x0, F0)
        x.axpy(1.0, d)
        self.residual(x, up)
        x.axpy(-2.0, d)
        self.residual(x, down)
        up.axpy(1.0, down)
        up.axpy(-2.0, F0)
        up.scale(-0.5)
        self.jacobian(x0).solve(up, F0)
        w, dnu = self.split(F0)
        for v in (x, up, down, F0):
            v.destroy()
        return w, dnu

    # -- stability ---------------------------------------------------------------
    def index(self, phi, nu):
        """The index of the state `phi` (nodal, with harmonics) with multipliers
        `nu` within the problem's harmonics: the negative eigenvalues of the
        Hessian of L on the constraints' tangent space, the negative pivots of
        its factored bordered Jacobian (`jacobian`, exact only with the
        `coupled` assembly: -pf_hessian coupled) less the ncon of the
        constraints. With cosines only, no rigid motion is left free: n >= 2
        holds none, and with n = 1 (a half box) X pins the translation across
        the axis. Collective."""
        if self.assembly.krylov:
            raise ValueError("an index needs the exact Hessian: -pf_hessian coupled")
        self.nu = nu
        x = self.vec(phi)
        self.assembly.hold(x)
        ksp = self.jacobian(x)
        ksp.setUp()
        nneg = self.negative_pivots(ksp)
        return None if nneg is None else nneg - self.ncon

    def modes(self, phi, nu_area, nev=3):
        """The mode Hessians of the state `phi` (nodal) with tension `nu_area`
        (`parallel.stability.ModeAnalysis`), its eigensolver under the prefix +
        'modes_'; closed with the problem."""
        from pfmembrane.parallel.stability import ModeAnalysis
        analysis = ModeAnalysis(self, phi, nu_area, nev)
        self._analyses.append(analysis)
        return analysis

    # -- lifetime ----------------------------------------------------------------
    def close(self, collective=True):
        """Restore the options database and, `collective` (every rank here),
        destroy the PETSc objects. An error that may be one rank's alone ends
        in an abort of every rank (`__main__`), which a collective destroy on
        the failing rank would never reach: `__exit__` skips it then."""
        try:
            if collective:
                for analysis in self._analyses:
                    analysis.destroy()
                self._analyses.clear()
                self.solver.destroy()
                self.assembly.destroy()
        finally:
            self.options.close()

    def __enter__(self):
        return self

    def __exit__(self, kind, value, traceback):
        self.close(collective=kind is None or issubclass(kind, (UsageError, GeneratorExit)))

def assembly(discrete, eps, scene, coupled=False):
    """The assembly of `scene` on a grid's discretization: axisymmetric, or
    with the scene's harmonics (their exact `coupled` Hessian factored, or
    its block-diagonal model)."""
    args = (discrete, eps, scene.k, scene.c0, (scene.area, scene.volume), scene.zc)
    if not scene.harmonics:
        return Assembly(*args)
    from pfmembrane.parallel.harmonic import HarmonicAssembly
    return HarmonicAssembly(*args, scene.harmonic_set, coupled)


_count = itertools.count(1)


def path_line(path):
    """One line on the energy path (E on the constraints at each iterate):
    whether it falls all the way, else where and by how much it rises. The
    constraints hold to PROJECT_RTOL, so E on them is known to about that
    much of itself: smaller rises are rounding."""
    rises = np.flatnonzero(np.diff(path) > PROJECT_RTOL * abs(path[0]))
    if not len(rises):
        return f"energy path: E on the constraints falls at every one of {len(path)} iterates"
    return (f"energy path: E on the constraints rises at {len(rises)} of {len(path) - 1} "
            f"iterations (first at {rises[0] + 1}, most by {np.diff(path).max():.3g})")


def next_prefix():
    """An options prefix of its own for a problem, 'pfN_' (N counts them):
    `-pfN_stage2_snes_monitor` on the command line reaches that problem only."""
    return f"pf{next(_count)}_"
