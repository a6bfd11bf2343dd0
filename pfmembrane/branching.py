"""Continuation of a branch of equilibria in a scene parameter: the secant and
Euler predictors, the tangent and the critical mode from one factorization,
Keller's pseudo-arclength corrector, step control, folds, bifurcations and
branch switching; where a branch is left (`bifurcation`, `asymmetric`,
`topology_lost`).

Written against a `parallel.problem.Problem`: its residual F(x, nu; p), its
Jacobian factored (`Problem.jacobian`, with its inertia) and its parameter
derivative F_p; the Vec algebra is petsc4py's, the Vecs the problem's.
"""
import itertools
import math
import warnings
from typing import NamedTuple

import numpy as np

from pfmembrane.analysis.checks import ENERGETIC, phase_field_checks
from pfmembrane.parallel.problem import PARAMETERS, Problem, next_prefix
from pfmembrane.parallel.solver import SolveError
from pfmembrane.result import Result, multiplier_names

CRITICAL_IT = 12  # inverse iterations for the critical mode at a bifurcation
# The arclength corrector keeps its factorization once |F| is below CHORD_RTOL of the
# predictor's (there a chord step gains as much as a Newton step's last digits need),
# as long as each step cuts |F| by CHORD_GAIN (runs/atlas/notes.md).
CHORD_RTOL = 1e-5
CHORD_GAIN = 0.1
# A continuation step is retried at half the length when its corrector needs more than
# CORRECTOR_MAX_IT Newton steps (factorizations; 3-4 on a regular stretch, then chord
# steps) or lands farther than JUMP steps from the last point: both are how a long step
# onto another branch shows (runs/atlas/notes.md).
CORRECTOR_MAX_IT = 7
JUMP = 2.0
GROW_IT = 3  # a corrector of at most this many factorizations lets the next step grow


def predict(older, newer, ratio=1.0):
    """The secant predictor of a continuation: phi and the multipliers of
    `newer` + `ratio` (`newer` - `older`), a start for the next solve on
    `newer`'s grid (`ratio`: the next parameter step over the last one)."""
    if older.nodes.shape != newer.nodes.shape or not np.array_equal(older.nodes, newer.nodes):
        raise ValueError("predict needs two results on the same nodes")
    phi = newer.phi + ratio * (newer.phi - older.phi)
    nu = newer.nu + ratio * (newer.nu - older.nu)
    attrs = {**newer.attrs, **dict(zip(multiplier_names(newer.attrs), nu)), 'converged': 1}
    return Result(newer.nodes, phi, attrs, grid=newer.grid, path=newer.path)


class Tangent(NamedTuple):
    """d(phi, nu)/dp along a branch: `phi` nodal (0 on the Dirichlet nodes)."""
    parameter: str
    phi: np.ndarray
    nu: np.ndarray


class Branch:
    """A converged result's state as a distributed Vec `x` of its `problem`
    (under `prefix`, or one of its own), which `at` moves along `parameter`.
    Collective; a context manager that closes the problem."""

    def __init__(self, result, parameter, options=None, prefix=None):
        if parameter not in PARAMETERS:
            raise ValueError(f"no continuation in {parameter!r}: one of "
                             f"{', '.join(PARAMETERS)}")
        if result.grid is None or not result.converged:
            raise ValueError("a branch starts from a converged result on its grid (a solve's)")
        self.result, self.parameter, self.grid = result, parameter, result.grid
        self.scene = result.scene
        if self.scene.harmonics:
            # the corrector factors the exact Jacobian: its inertia is the index and shows
            # folds and bifurcations, which the block-diagonal model's would not
            options = {'pf_hessian': 'coupled', **(options or {})}
            if options['pf_hessian'] != 'coupled':
                raise ValueError("a branch with harmonics is followed with the exact "
                                 "Hessian: pf_hessian 'coupled'")
        self.problem = Problem(self.grid, self.scene, result.eps, prefix or next_prefix(),
                               options)
        self.x = self.problem.vec(result.phi)
        self.problem.assembly.hold(self.x)
        self.problem.nu = result.nu
        self.checked = {}  # what `phase_field_checks` keeps between this branch's points

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return self.problem.__exit__(*exc)


def tangent(result, parameter='reduced_volume', options=None, prefix=None):
    """The tangent of `result`'s branch in a scene parameter (`PARAMETERS`):
    dX/dp from one Jacobian factorization at the converged state
    (`branch_tangent`). Collective on the result's grid. `options` as for
    `solve` (the factorization reads `stage2_` options under the prefix)."""
    with Branch(result, parameter, options, prefix) as branch:
        (dx, dnu), _ = branch_tangent(branch.problem, branch.x, parameter,
                                      getattr(branch.scene, parameter))
        return Tangent(parameter, branch.problem.nodal(dx, 0.0), dnu)


def continuation(result, parameter, ds, steps, ds_max=None, options=None, prefix=None,
                 checks=False, switch=False):
    """Pseudo-arclength continuation of `result`'s branch in a scene parameter
    (`PARAMETERS`), in this process on the result's grid. Collective.

    Yields a `Result` per point, `steps` of them or fewer should the step
    have to shrink below ds / 64. The arclength s is measured in the norm
    |(x, p)|^2 = x . x / n + p^2 of the n free nodal values x (their RMS) and
    the parameter p (`arclength`), the first step in the direction
    of increasing parameter for ds > 0. The step grows by 1.5 after a
    corrector of at most GROW_IT factorizations (to `ds_max`, by default 4 |ds|)
    and halves after a failed one (`CORRECTOR_MAX_IT`, `JUMP`). Each result's
    attrs carry the parameter, `arclength`, `index_0` (negative eigenvalues
    of the Hessian of the Lagrangian on the constraints' tangent space: the
    factorization's inertia minus the constraints), `dp_ds` and `fold` (1
    where dp/ds changed sign since the previous point) and `index_change` (1
    where index_0 changed without a fold: a bifurcation passed); `result`'s
    own attrs get its `index_0`, from the factorization of the first tangent.
    `checks` runs the phase-field checks at every point (`solve`'s).

    With `switch`, the branch left is the one crossing `result`'s at a
    bifurcation near it: the first tangent is the critical mode there (the
    eigenvector of that Hessian whose eigenvalue is nearest zero, `critical_mode`, stored as `result`'s attr `critical_eigenvalue`) with no
    parameter change, and ds > 0 and ds < 0 go to its two sides.
    """
    with Branch(result, parameter, options, prefix) as branch:
        yield from _follow(branch, result, parameter, ds, steps, ds_max, checks, switch)


def _follow(branch, result, parameter, ds, steps, ds_max, checks, switch):
    """The points of `continuation` on `branch`."""
    problem, x = branch.problem, branch.x
    p = getattr(branch.scene, parameter)
    ds_max = ds_max or 4 * abs(ds)
    sign = 1.0 if ds > 0 else -1.0
    if switch:
        mx, mnu, value, negative = critical_mode(problem, x)
        mx.scale(sign)
        t = (mx, sign * mnu, 0.0)
        result.attrs['critical_eigenvalue'] = value
    else:
        (bx, bnu), negative = branch_tangent(problem, x, parameter, p)
        t = _unit(bx, bnu, sign)
    start = None if negative is None else negative - problem.ncon
    result.attrs['index_0'] = -1 if start is None else start
    step, s, previous = abs(ds), 0.0, (t[2], start)
    behind = None  # the point before this one and the step between them
    for _ in range(steps):
        x_old, nu_old = x.copy(), problem.nu.copy()
        try:
            p_new, its, factored, negative, (bx, bnu) = arclength(
                problem, x, parameter, p, t, step, CORRECTOR_MAX_IT,
                _bend(behind, x, nu_old, p, t, step))
            if _distance(x, x_old, p_new - p) > JUMP * step:
                raise SolveError("the corrector left the step's neighbourhood")
        except SolveError:
            x_old.copy(x)
            problem.nu = nu_old
            problem.at(parameter, p)
            step /= 2
            if step < abs(ds) / 64:
                warnings.warn(f"continuation in {parameter} stopped at {p:g}: the "
                              f"corrector failed down to a step of {step:.3g}",
                              stacklevel=2)
                return
            continue
        s += step
        behind = (x_old, nu_old, p, step)
        p = p_new
        # the new tangent continues the old one: (b, 1) oriented by t
        t_new = _unit(bx, bnu, 1.0)
        if t[0].dot(t_new[0]) / x.getSize() + t[2] * t_new[2] < 0:
            t_new = _unit(bx, bnu, -1.0)
        index = None if negative is None else negative - problem.ncon
        fold = int(previous[0] != 0 and np.sign(t_new[2]) != np.sign(previous[0]))
        changed = int(previous[1] is not None and index is not None
                      and index != previous[1] and not fold)
        t, previous = t_new, (t_new[2], index)
        yield _point(branch, p, s, index, t_new[2], fold, changed, its, checks)
        step = min(1.5 * step, ds_max) if factored <= GROW_IT else step


def _bend(behind, x, nu, p, t, ds):
    """The second-order term of the predictor at (x, nu, p) with unit tangent t for
    a step ds: (ds / h)^2 (X_behind - X + h t), with X_behind the point a step h
    back, X(s - h) = X - h t + h^2 X'' / 2 + O(h^3). None for a branch's first
    step. It takes the corrector's start from O(ds^2) to O(ds^3) off the branch
    (runs/atlas/notes.md)."""
    if behind is None:
        return None
    xb, nub, pb, h = behind
    w = (ds / h) ** 2
    bx = xb.copy()
    bx.axpy(-1.0, x)
    bx.axpy(h, t[0])
    bx.scale(w)
    return bx, w * (nub - nu + h * np.asarray(t[1])), w * (pb - p + h * t[2])


def _distance(x, y, dp):
    """|(x - y, dp)| in the norm of `arclength`."""
    d = x.copy()
    d.axpy(-1.0, y)
    return math.hypot(d.norm() / math.sqrt(x.getSize()), dp)


def _unit(bx, bnu, sign):
    """The unit tangent (t_x, t_nu, t_p) along (sign b_x, sign b_nu, sign) in the
    norm of `arclength`."""
    norm = math.sqrt(bx.dot(bx) / bx.getSize() + 1.0)
    tx = bx.copy()
    tx.scale(sign / norm)
    return tx, sign * np.asarray(bnu) / norm, sign / norm


def _point(branch, p, s, index, dp_ds, fold, changed, its, checks):
    """The Result of a converged point of a continuation."""
    res, problem = branch.result, branch.problem
    vals = problem.assembly.values(branch.x)
    nu = problem.nu
    attrs = {**res.attrs, branch.parameter: p, 'energy': vals[0], 'area': vals[1],
             'volume': vals[2], 'moment': vals[3], 'moment_x': vals[4],
             **dict(zip(multiplier_names(res.attrs), nu)),
             'converged': 1, 'arclength': s, 'index_0': -1 if index is None else index,
             'dp_ds': dp_ds, 'fold': fold, 'index_change': changed,
             'stage1_iterations': -1, 'stage2_iterations': its,
             'max_phi': problem.assembly.max_abs_phi(branch.x), 'parent': ''}
    for key in ('sharp_energy', 'sharp_rel_error', 'sharp_dist_max', 'sharp_dist_mean',
                'level_set_energy', 'topology', 'components', 'genus', 'torus_radii',
                'index_m', 'lowest_m', 'time_modes', 'sharp_note',
                'component_energies', 'feature_size', 'feature_kind'):
        attrs.pop(key, None)
    phi = problem.nodal(branch.x, -1.0)
    if checks:
        attrs.update(phase_field_checks(branch.grid.comm.tompi4py(), branch.grid.nodes, phi,
                                        attrs, branch.checked))
    return Result(branch.grid.nodes, phi, attrs, grid=branch.grid)


def along(result, tangent, step):
    """The Euler predictor of a continuation: `result` moved by `step` in the
    tangent's parameter, a start for the solve there (on `result`'s grid)."""
    phi = result.phi + step * tangent.phi
    nu = result.nu + step * tangent.nu
    attrs = {**result.attrs, **dict(zip(multiplier_names(result.attrs), nu)), 'converged': 1,
             tangent.parameter: float(result.attrs[tangent.parameter]) + step}
    return Result(result.nodes, phi, attrs, grid=result.grid, path=result.path)


def branch_tangent(problem, x, parameter, p):
    """((dx, dnu), negative pivots): dX/dp of the converged state (x, nu)
    along its branch, J dX/dp = -F_p with J the stage-2 Jacobian there (one
    factorization), and that factorization's negative pivots (None
    without inertia)."""
    Fp = problem.parameter_derivative(x, parameter, p, problem.bordered_vec())
    ksp = problem.jacobian(x)
    Fp.scale(-1.0)
    b = problem.bordered_vec()
    ksp.solve(Fp, b)
    return problem.split(b), problem.negative_pivots(ksp)


def critical_mode(problem, x, iterations=CRITICAL_IT):
    """(m_x, m_nu, eigenvalue, negative pivots): the eigenvector of the Hessian of
    the Lagrangian on the constraints' tangent space whose eigenvalue is nearest
    zero, by inverse iteration with the stage-2 Jacobian at (x, nu) (one
    factorization; a solve with the right-hand side (y, 0) applies the inverse of
    that Hessian to y's part in the tangent space). At a bifurcation it points along
    the branch that crosses this one. The start mixes every symmetry (up-down
    antisymmetric modes too)."""
    lay = problem.layout
    ksp = problem.jacobian(x)
    rhs, sol = ksp.getOperators()[0].createVecs()
    rhs.zeroEntries()  # the constraint rows stay 0
    y, z = x.duplicate(), x.duplicate()
    y.setArray(np.sin(1.0 + 0.618034 * np.arange(lay.start, lay.start + lay.nowned)))
    value = math.nan
    for _ in range(iterations):
        y.scale(1.0 / y.norm())
        rhs.getArray()[:lay.nowned] = y.getArray(readonly=True)
        ksp.solve(rhs, sol)
        z.setArray(sol.getArray(readonly=True)[:lay.nowned])
        value = 1.0 / y.dot(z)  # |y| = 1: the inverse's Rayleigh quotient, inverted
        z.copy(y)
    _, nu = problem.split(sol)
    scale = math.sqrt(y.getSize()) / y.norm()  # unit RMS, the arclength norm
    y.scale(scale)
    return y, scale * nu, value, problem.negative_pivots(ksp)


def arclength(problem, x, parameter, p, t, ds, max_it=25, bend=None):
    """The pseudo-arclength corrector (Keller's bordering): Newton on
    F(x, nu; p) = 0 with N = t_x . (x - x0) + t_p (p - p0) - ds = 0, from
    the predictor (x0 + ds t_x, nu + ds t_nu, p0 + ds t_p) plus `bend`.

    `t` = (t_x Vec, t_nu, t_p) with (t_x, t_p) a unit vector in the norm
    |(x, p)|^2 = x . x / n + p^2 (n free values: an RMS of phi); `bend`
    (b_x Vec, b_nu, b_p), if given, is the predictor's second-order term.
    Each iteration solves J a = -F, J b = -F_p: the step is a + dp b, dp
    making N vanish to first order; b is dX/dp there. J is factored again
    unless |F| is below CHORD_RTOL of the predictor's and the last step cut
    it by CHORD_GAIN (then a chord step: Newton has converged but for its
    last digits). Returns (p, iterations, factorizations,
    negative pivots of the last factorization, (b_x, b_nu)); x and nu are
    updated in place. Raises SolveError where `max_it` Newton steps (on as
    many factorizations; chord steps do not count) have not converged.
    """
    P, solver = problem.assembly, problem.solver
    K = P.bordered_matrix()
    ksp = solver.direct_ksp('stage2_')
    F, Fp, a, b = (K.createVecLeft() for _ in range(4))
    tx, tnu, tp = t
    x0, p0 = x.copy(), p
    x.axpy(ds, tx)
    solver.nu = solver.nu + ds * np.asarray(tnu)
    p = p0 + ds * tp
    if bend is not None:
        x.axpy(1.0, bend[0])
        solver.nu = solver.nu + np.asarray(bend[1])
        p += bend[2]
    dx, n = x.duplicate(), x.getSize()
    norm0 = last = None
    factored, converged = 0, False
    for it in itertools.count():
        problem.parameter_derivative(x, parameter, p, Fp)
        problem.residual(x, F)
        x.copy(dx)
        dx.axpy(-1.0, x0)
        N = tx.dot(dx) / n + tp * (p - p0) - ds
        norm = F.norm()
        norm0 = norm if norm0 is None else norm0
        converged = (it > 0 and norm <= max(problem.settings.stage2_rtol * norm0, 1e-12)
                     and abs(N) < 1e-10 * abs(ds))
        if converged:
            break
        if not (it and norm <= CHORD_RTOL * norm0 and norm <= CHORD_GAIN * last):
            if factored == max_it:
                break
            factored += 1
            P.assemble_bordered(x, solver.nu[0], solver.C, 0.0)
            ksp.setOperators(K)
            solver.factorizations += 1
        last = norm
        F.scale(-1.0)
        ksp.solve(F, a)
        Fp.scale(-1.0)
        ksp.solve(Fp, b)
        ax, _ = problem.split(a)
        bx, _ = problem.split(b)
        dp = -(N + tx.dot(ax) / n) / (tx.dot(bx) / n + tp)
        a.axpy(dp, b)
        step_x, step_nu = problem.split(a)
        x.axpy(1.0, step_x)
        solver.nu = solver.nu + step_nu
        p += dp
        problem.at(parameter, p)
    if not converged:
        raise SolveError(f"the arclength corrector did not converge in {max_it} Newton "
                         f"iterations (|F| {norm:.2e}); try a shorter step")
    return p, it, factored, problem.negative_pivots(ksp), problem.split(b)


# Where a branch is left: its first bifurcation, a shape off its symmetry, a topology
# without a level-set energy.
REFINE = 4          # step ratio of each bracketing of a bifurcation (`bifurcation`)
ASYMMETRY = 5e-3    # up-down asymmetry (over R) past which a full-box shape is a pear
OTHER_TOPOLOGY = 3  # points of a topology without a level-set energy that end a branch


def bifurcation(start, parameter, ds, steps, bound, options=None, say=None,
                through_folds=True, left=None, scale=1.0):
    """Where `start`'s branch, continued in `parameter` from steps `ds`
    (`continuation`, at most `steps` points a bracketing), first changes its
    stability index without a fold (a bifurcation passed).

    Returns (a point just past that change, its `parameter`, whether it left
    the branch), or (None, the farthest value reached, False) where there is
    none before `bound`, before a fold (unless `through_folds`: then it goes
    on past folds) or before the continuation ends. A point on which `left`
    holds (it lost the branch's symmetry: `asymmetric`) counts as a change
    too: near a pitchfork the corrector can land on the crossing branch, and
    where that one turns back the step reads as a fold. The change is
    bracketed again from the point before it with steps REFINE times shorter,
    twice, so that a switch (`continuation(..., switch=True)`) starts near
    the bifurcation. Each point is reported through `say`, its parameter
    times `scale`; only the one returned gets the phase-field checks.
    `options` as for `continuation`. Collective on the result's grid."""
    sign = math.copysign(1.0, ds)
    value = farthest = start.attrs[parameter]
    before = start
    for level in range(3):
        for res in continuation(before, parameter, ds, steps,
                                ds_max=abs(ds) if level else None, options=options,
                                checks=False):
            value = res.attrs[parameter]
            farthest = max(farthest * sign, value * sign) * sign
            jumped = bool(left and left(res))
            if say is not None:
                say(f"{parameter} {scale * value:.4f} index {res.attrs['index_0']} "
                    f"(step {scale * abs(ds):g})" + (' fold' if res.attrs['fold'] else '')
                    + (' off the branch' if jumped else ''))
            if res.attrs['index_change'] or jumped:
                break
            if sign * (value - bound) > 0 or (res.attrs['fold'] and not through_folds):
                return None, farthest, False
            before = res
        else:
            return None, farthest, False
        ds /= REFINE
    res.attrs.update(phase_field_checks(res.grid.comm.tompi4py(), res.grid.nodes,
                                        res.phi, res.attrs))
    return res, value, jumped


def asymmetric(result, tolerance=ASYMMETRY):
    """Whether the level set phi_h = 0 of a full-box result is up-down
    asymmetric by more than `tolerance` times its scene's radius
    (`levelset.up_down_asymmetry`): a pear, not a prolate. A `left` of
    `bifurcation`: every rank computes it alike."""
    from pfmembrane.analysis import levelset
    curve = levelset.level_set(result.checkpoint().unfolded())
    return bool(curve) and abs(levelset.up_down_asymmetry(curve, result.scene.radius)) > tolerance


def topology_lost(topologies, count=OTHER_TOPOLOGY):
    """Whether the last `count` of a branch's topologies (of phi_h = 0, in
    order) are all without a level-set energy (not in `checks.ENERGETIC`: a
    bud pinched off, several spheres): where the studies end a branch."""
    return len(topologies) >= count and all(t not in ENERGETIC for t in topologies[-count:])
