"""Equilibria and their stability: a solve of a scene on a grid, the
azimuthal spectra of a solved state. Each runs one `parallel.problem.Problem`,
which owns its options and PETSc objects and closes with the call."""
import dataclasses
import math
import resource
import time
import warnings

import numpy as np
from mpi4py import MPI

from pfmembrane.analysis.checks import phase_field_checks, surface_checks
from pfmembrane.grid import Grid
from pfmembrane.io.options import STARTS_3D, UsageError
from pfmembrane.kernels.azimuthal import RIGID
from pfmembrane.parallel import petsc
from pfmembrane.parallel.problem import Problem, next_prefix
from pfmembrane.result import Result, multiplier_names
from pfmembrane.starts import kind_of, start_phi, start_topology

# Log events whose times a result reports: functionals and their derivatives
# into Vec/Mat, and the linear solves (factorizations included).
ASSEMBLY_EVENTS = ('pfFunctional', 'pfGradient', 'pfHessian', 'pfMatAssembly')
LINEAR_EVENTS = ('PCSetUp', 'KSPSolve')
# A harmonic pushed at the start whose largest |psi_m| falls below this has
# returned to the axisymmetric state (rounding leaves 1e-12 at one that
# stays there, `tests/parallel/test_harmonic_solve.py`).
SADDLE_AMPLITUDE = 1e-8
# The curved push samples L along its path at these t (units of -pf_perturb) and fits
# L(t) - L(0) = alpha t^2 + beta t^4 + gamma t^6: gamma takes up the path's own error (its
# terms of order t^3 and up), so that alpha and beta are the reduced energy's and the
# branch's amplitude is t* = sqrt(-alpha / (2 beta)) (Lyapunov-Schmidt, to leading order).
CURVE_SAMPLES = (0.5, 1.0, 1.5)
# No push moves |psi| beyond this, half the phase field's range: there it moves the
# interface by more than its width, where the path's expansion means nothing.
PUSH_MAX = 0.5


def solve(scene, grid, eps, start=None, options=None, prefix=None, checks=False):
    """The equilibrium shape of `scene` on `grid` at width `eps`. Collective.

    Starts from the scene's initial shape (option `pf_start`,
    `io.options.STARTS`), or from `start` (a `Result`: on this grid, read from
    a file, or the parent of an adapted grid). `options` maps
    command-line names without the dash to values, PETSc's (`stage2_snes_monitor`,
    `stage1_tao_type`) and the solver's own (`pf_stage1`, `pf_mu`,
    `pf_stage1_rtol`, `pf_stage1_max_it`, `pf_stage2_rtol`, `pf_monitor`,
    `pf_force`, `pf_start`, `pf_summary`, `pf_path`); they live under the solve's options
    `prefix` (by default one of its own, so `-PREFIX...` on the command line
    reaches only this solve) and leave the database as they found it
    (`parallel.problem.Problem`); those nothing used are warned of and listed
    in the result's `unused_options`. `checks` runs the phase-field checks of
    a converged field (`analysis.checks`: the level set's topology and own
    energy, the sharp-interface shape's).

    A scene with harmonics from a fresh axisymmetric start first solves its
    axisymmetric part (the direct solver's few steps take it most of the way),
    then lifts it (`critical_start`): each harmonic m whose mode Hessian has a
    negative eigenvalue there starts along that critical mode with amplitude
    `pf_perturb`, the others at 0, so the solve leaves the axisymmetric
    family's saddle downhill and does not wander where it is stable; one
    harmonic pushed, the push follows the branch's centre manifold to its
    leading-order amplitude (`pf_push` curved). The result's times are the
    sum, its `energy_history` (E at every iteration; with `pf_path` also
    `energy_path`, E of each iterate put on the constraints) the harmonic
    solve's, `start_unstable_m` the harmonics pushed, `start_push` the push's
    largest |psi|.

    Returns a `Result`; one that did not converge has `converged` False and
    the reason in `message`. Raises `io.options.UsageError` for bad input.
    """
    if scene.harmonics and start is None and \
            kind_of(scene, (options or {}).get('pf_start', 'auto')) not in STARTS_3D:
        # its energy path would be discarded with it: the result's is the harmonic solve's
        axisymmetric = _solve(dataclasses.replace(scene, harmonics=0), grid, eps, None,
                              {**(options or {}), 'pf_path': False}, None, False)
        if not axisymmetric.converged:
            return axisymmetric
        t = time.perf_counter()
        lift, unstable = critical_start(axisymmetric, scene, grid, options)
        t = time.perf_counter() - t
        result = _solve(scene, grid, eps, lift, options, prefix, checks)
        result.unused_options = [k for k in result.unused_options
                                 if k in axisymmetric.unused_options]
        for name in ('wall_time', 'time_stage1', 'time_stage2', 'time_assembly', 'time_linear',
                     'time_setup'):
            result.attrs[name] += axisymmetric.attrs[name]
        result.attrs['wall_time'] += t
        result.attrs.update(start_unstable_m=unstable, start_push=lift.attrs['start_push'],
                            time_lift=t)
        back = returned(result, unstable)
        if back:
            result.attrs['saddle'] = 1
            warnings.warn(f"the solve returned to the axisymmetric state, which is unstable "
                          f"to m = {', '.join(map(str, back))}: a saddle, not a minimum (a "
                          "tighter stage 1, -pf_stage1_rtol, or a larger -pf_perturb may leave "
                          "it)", stacklevel=2)
        result.attrs.update(parent='', start_topology=axisymmetric.attrs['start_topology'])
    else:
        result = _solve(scene, grid, eps, start, options, prefix, checks)
    before, after = result.attrs.get('start_topology', ''), result.attrs.get('topology', '')
    if before and after and before != after:
        warnings.warn(f"the level set changed topology: the start was {before}, phi_h = 0 is "
                      f"{after}", stacklevel=2)
    if result.unused_options:
        warnings.warn("solve options never used: "
                      f"{', '.join('-' + k for k in result.unused_options)}", stacklevel=2)
    return result


def critical_start(axisymmetric, scene, grid, options=None):
    """The start of `scene`'s harmonics from its solved axisymmetric part:
    phi (nodes x harmonics) with psi_m = r^m chi_m cos(m theta) along the
    lowest eigenvector of mode m's Hessian where that eigenvalue is negative
    (`parallel.stability`; rigid motions excluded), scaled so that the largest
    |psi_m| at a node is the scene's `pf_perturb`, and 0 where mode m is
    stable (the sign of an eigenvector is a rotation by pi / m). Collective.

    One harmonic pushed, the push is curved by default (-pf_push, `_curved`).
    Returns the start (a `Result` on `grid`, converged as the axisymmetric
    one, the push's largest |psi| in `start_push`) and the array of the m
    pushed.
    """
    h = scene.harmonic_set
    phi = np.zeros((len(axisymmetric.phi), len(h)))
    phi[:, 0] = axisymmetric.phi
    unstable = []
    r = grid.nodes[:, 0]
    with Problem(grid, dataclasses.replace(scene, harmonics=0), axisymmetric.eps,
                 next_prefix(), options) as problem:
        perturb = problem.settings.perturb
        analysis = problem.modes(axisymmetric.phi, axisymmetric.nu[0], 1)
        for j, m in enumerate(h.m):
            if m == 0:
                continue
            lowest, vector = _critical(analysis.spectrum(m))
            if not lowest < 0:
                continue
            chi = problem.nodal(vector, 0.0)
            phi[:, j] = perturb * chi / np.abs(r ** m * chi).max()
            unstable.append(int(m))
            if problem.settings.summary:
                PETSc = petsc.start()
                PETSc.Sys.Print(f"start: the axisymmetric state is unstable to m = {m} "
                                f"(lowest eigenvalue {lowest:.4g}): pushed along it by "
                                f"{perturb:g}", comm=grid.comm)
        curved = len(unstable) == 1 and problem.settings.push == 'curved'
    lift = dataclasses.replace(axisymmetric, phi=phi,
                               attrs={**axisymmetric.attrs, 'start_push': perturb})
    return _curved(lift, scene, grid, options) if curved else lift, np.array(unstable, dtype=int)


def _curved(lift, scene, grid, options):
    """The start `lift` (the solved axisymmetric state pushed along one critical
    mode, by -pf_perturb) moved along the centre manifold to second order
    (`parallel.problem.Problem.slaved`): x0 + t d + t^2 w, nu + t^2 dnu, to
    the t where the reduced energy alpha t^2 + beta t^4 (CURVE_SAMPLES) is
    least, t* = sqrt(-alpha / (2 beta)) (at most PUSH_MAX). Where beta <= 0 (the
    branch turns back: a subcritical bifurcation) `lift` as it is. Records the
    push's largest |psi| in `start_push`. Collective."""
    with Problem(grid, scene, lift.eps, next_prefix(), options) as problem:
        perturb, summary = problem.settings.perturb, problem.settings.summary
        axisymmetric = np.zeros_like(lift.phi)
        axisymmetric[:, 0] = lift.phi[:, 0]
        x0, d = problem.vec(axisymmetric), problem.vec(lift.phi - axisymmetric)
        x, nu0 = x0.duplicate(), np.zeros(problem.ncon)
        nu0[:len(lift.nu)] = lift.nu
        x0.copy(x)
        x.axpy(1.0, d)
        problem.assembly.hold(x)  # the rigid motions where the straight push puts them
        problem.nu = nu0
        w, dnu = problem.slaved(x0, d)

        def along(t):
            x0.copy(x)
            x.axpy(t, d)
            x.axpy(t * t, w)
            return x, nu0 + t * t * dnu

        L0 = problem.lagrangian(*along(0.0))
        samples = np.array(CURVE_SAMPLES)
        alpha, beta, _ = np.linalg.solve(
            np.column_stack([samples ** 2, samples ** 4, samples ** 6]),
            [problem.lagrangian(*along(s)) - L0 for s in samples])
        t = min(math.sqrt(-alpha / (2.0 * beta)), PUSH_MAX / perturb) \
            if alpha < 0 < beta else None
        if t is not None:
            x, nu = along(t)
            phi = problem.nodal(x, -1.0)
        for v in (x0, d, x, w):
            v.destroy()
    if t is None:
        if summary:
            petsc.start().Sys.Print(
                f"start: the reduced energy {alpha:.4g} t^2 + {beta:.4g} t^4 has no least "
                f"value: pushed straight by {perturb:g}", comm=grid.comm)
        return lift
    if summary:
        petsc.start().Sys.Print(
            f"start: curved push to {t * perturb:.4g} (the reduced energy {alpha:.4g} t^2 + "
            f"{beta:.4g} t^4 least at t = {t:.3g}, t in units of {perturb:g})", comm=grid.comm)
    names = multiplier_names(lift.attrs)
    return dataclasses.replace(lift, phi=phi, attrs={**lift.attrs, **dict(zip(names, nu)),
                                                     'start_push': t * perturb})


def returned(result, unstable):
    """The harmonics m among `unstable` (pushed at the start) whose largest
    |psi_m| at a node the converged `result` brought back below
    SADDLE_AMPLITUDE: it rests on the axisymmetric state, unstable to them."""
    if not result.converged:
        return []
    h, r = result.scene.harmonic_set, result.nodes[:, 0]
    return [int(m) for j, m in enumerate(h.m)
            if m in unstable and np.abs(r ** m * result.phi[:, j]).max() < SADDLE_AMPLITUDE]


def _solve(scene, grid, eps, start, options, prefix, checks):
    """`solve` from `start`, its unused options not yet warned of."""
    if not grid.fits(scene):
        raise UsageError(
            f"the scene (box {scene.box}, {'half' if scene.symmetric else 'full'} box) "
            f"does not fit the grid (box {grid.box}, {'half' if grid.symmetric else 'full'} box)")
    if not (math.isfinite(eps) and eps > 0):
        raise UsageError(f"-pf_eps must be > 0 (got {eps!r})")
    comm = grid.comm
    mpi = comm.tompi4py()
    t0 = time.perf_counter()
    with Problem(grid, scene, eps, prefix or next_prefix(), options) as problem:
        under = eps < grid.eps_min
        if under and not problem.settings.force:
            raise UsageError(
                f"eps {eps:g} is below what this grid resolves (eps_min = {grid.eps_min:.4g}); "
                "use more nodes, an adapted grid, or -pf_force to run anyway")
        phi0, nu0, solved = start_phi(scene, grid, eps, start, problem.settings.start,
                                      problem.settings.perturb)
        x = problem.vec(phi0)
        # Failures of the solve end in `state`; anything else propagates at once,
        # with no collective cleanup that a rank still computing would never reach.
        converged, message, status, vals, stages = problem.solve(x, nu0, solved)
        phi = problem.nodal(x, -1.0)
        max_phi = problem.assembly.max_abs_phi(x)
        nu, stats = problem.nu, problem.solver.stats
        history = np.array(problem.solver.history)
        path = np.array(problem.solver.path) if problem.settings.path else None
        factorizations = problem.solver.factorizations
        unused = [k[len(problem.prefix):] for k in problem.options.unused(mpi)]
        topology0 = start_topology(scene, start, problem.settings.start)
    setup = grid.setup_time if grid.setup_pending else 0.0
    adapt_f, adapt_band, adapt_time = (
        (grid.adapt_info['f'], grid.adapt_info['band'], grid.adapt_info['time'])
        if grid.setup_pending and grid.adapt_info else (0.0, 0.0, np.nan))
    grid.setup_pending = False
    attrs = dict(energy=vals[0], area=vals[1], volume=vals[2], moment=vals[3],
                 moment_x=vals[4], eps=eps, k=scene.k, c0=scene.c0,
                 gamma=grid.params['gamma'], symmetric=int(scene.symmetric), converged=int(converged),
                 wall_time=setup + time.perf_counter() - t0, n_procs=comm.getSize(),
                 cutoff=grid.params['cutoff'], quad_degree=grid.params['quad_degree'],
                 spacing_smoothing=grid.params['spacing_smoothing'],
                 spacing_floor=grid.params['spacing_floor'], radius=scene.radius,
                 reduced_volume=scene.reduced_volume, branch=scene.branch,
                 under_resolved=int(under), eps_min=grid.eps_min, n_nodes=grid.n_nodes,
                 max_phi=max_phi,
                 stage1_iterations=stats.get('stage1', {}).get('inner', -1),
                 stage2_iterations=stats.get('stage2', {}).get('iterations', -1),
                 stage2_linear_iterations=stats.get('stage2', {}).get('linear_iterations', -1),
                 factorizations=factorizations, adapt=adapt_f, adapt_band=adapt_band,
                 parent=start.path if start is not None else '',
                 start_topology=topology0,
                 time_setup=setup, time_adapt=adapt_time,
                 time_stage1=stats.get('stage1', {}).get('time', np.nan),
                 time_stage2=stats.get('stage2', {}).get('time', np.nan),
                 time_assembly=_event_seconds(mpi, ASSEMBLY_EVENTS, stages),
                 time_linear=_event_seconds(mpi, LINEAR_EVENTS, stages),
                 peak_rss_mb=mpi.allreduce(
                     resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=MPI.MAX),
                 box=np.asarray(scene.box), energy_history=history)
    if path is not None:
        attrs['energy_path'] = path
    if scene.harmonics:
        attrs.update(harmonics=scene.harmonic_set.m, harmonics_highest=scene.harmonics,
                     dihedral=scene.dihedral)
    attrs.update({'nu_moment': 0.0, **dict(zip(multiplier_names(attrs), nu))})
    if scene.harmonics:
        if converged and checks:
            attrs.update(surface_checks(mpi, grid.nodes, phi, attrs, grid.discrete.beta))
    elif converged and checks:  # an interrupted run checkpoints at once
        attrs.update(phase_field_checks(mpi, grid.nodes, phi, attrs))
    return Result(grid.nodes, phi, attrs, grid=grid, message=message, status=status,
                  unused_options=unused)


def stability(result, modes=6, nev=3, options=None, prefix=None, grid=None):
    """The azimuthal stability of an axisymmetric `result` against
    perturbations psi(r, z) cos(m theta), m = 0 ... `modes`
    (`parallel.stability`). Collective on the grid's communicator (`grid`, else
    the result's, else one rebuilt from its nodes).

    A result with harmonics gets its index within the scene's harmonics
    instead (the negative eigenvalues of the exact Hessian on the
    constraints' tangent space, from one factorization of the coupled
    bordered Hessian): returned, and recorded as `index_harmonics`.

    Returns one `parallel.stability.Spectrum` per m, its `vectors` as nodal chi
    (psi = r^m chi_h) on every rank, and records in `result.attrs` the index
    per m without the rigid motions (`index_m`) and the lowest eigenvalue per
    m (`lowest_m`), which `save` writes to the checkpoint. The eigensolver
    reads its options under `prefix` + 'modes_' (`-PREFIXmodes_eps_tol`;
    `options` as for `solve`, e.g. {'modes_eps_tol': 1e-12}); those nothing
    used are warned of and added to the result's `unused_options`.
    """
    grid = grid or result.grid or Grid.of(result)
    if result.scene.harmonics:
        return _harmonic_stability(result, grid, options, prefix)
    PETSc = petsc.start()
    stage = PETSc.Log.Stage('pfModes')
    stage.push()
    try:
        with Problem(grid, result.scene, result.eps, prefix or next_prefix(),
                     options) as problem:
            analysis = problem.modes(result.phi, result.nu[0], nev)
            spectra = []
            for m in range(modes + 1):
                s = analysis.spectrum(m)
                spectra.append(s._replace(vectors=[problem.nodal(chi, 0.0)
                                                   for chi in s.vectors]))
            unused = [k[len(problem.prefix):] for k in problem.options.unused(problem.mpi)]
    finally:
        stage.pop()
    if unused:
        warnings.warn(f"stability options never used: {', '.join('-' + k for k in unused)}",
                      stacklevel=2)
        result.unused_options = [*result.unused_options, *unused]
    result.attrs.update(
        index_m=np.array([s.index - np.count_nonzero((s.rigid > RIGID) & (s.eigenvalues < 0))
                          for s in spectra]),
        lowest_m=np.array([_critical(s)[0] for s in spectra]),
        time_modes=sum(s.time for s in spectra))
    return spectra


def _critical(spectrum):
    """The lowest eigenvalue of a mode's `spectrum` that is no rigid motion,
    and its vector: (NaN, None) without one."""
    return next(((e, v) for e, v, rigid in zip(spectrum.eigenvalues, spectrum.vectors,
                                                 spectrum.rigid) if not rigid > RIGID),
                (np.nan, None))


def _harmonic_stability(result, grid, options, prefix):
    """`stability` of a result with harmonics: its index within the scene's
    harmonics (`Problem.index`, the exact coupled Hessian factored once),
    recorded as `index_harmonics`. Returns None where the factorization gives
    no inertia."""
    PETSc = petsc.start()
    stage = PETSc.Log.Stage('pfModes')
    stage.push()
    t = time.perf_counter()
    try:
        with Problem(grid, result.scene, result.eps, prefix or next_prefix(),
                     {**(options or {}), 'pf_hessian': 'coupled'}) as problem:
            index = problem.index(result.phi, result.nu)
    finally:
        stage.pop()
    result.attrs.update(index_harmonics=-1 if index is None else index,
                        time_modes=time.perf_counter() - t)
    return index


def _event_seconds(mpi, names, stages):
    """Seconds spent in the named log events during the stages, max over ranks."""
    PETSc = petsc.start()
    mine = sum(PETSc.Log.Event(name).getPerfInfo(s.id)['time'] for name in names for s in stages)
    return mpi.allreduce(mine, op=MPI.MAX)
