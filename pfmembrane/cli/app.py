"""The application: read options, build the grid, solve both stages, checkpoint."""
import os
import resource
import sys
import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from pfmembrane.kernels import adapt
from pfmembrane.io import checkpoint
from pfmembrane.analysis import limit
from pfmembrane.kernels import nodes as nodesets
from pfmembrane.io import options
from pfmembrane.parallel.assembly import Problem
from pfmembrane.kernels.nodes import spacing_peak
from pfmembrane.parallel.discretization import Grid
from pfmembrane.kernels.basis import locality
from pfmembrane.kernels.initial import rescaled_phi, spheroid_phi
from pfmembrane.parallel.solver import Solver, SolveError
from pfmembrane.parallel.faults import Interrupted

# eps >= RESOLUTION * h_min, h_min the left peak of the mean-neighbour-distance
# distribution: calibrated on the paper's Tables 1-5 (admitted eps/h = 1.67-1.76,
# refused 1.18-1.25).
RESOLUTION = 1.5
# Log events whose times the checkpoint reports: functionals and their derivatives
# into Vec/Mat, and the linear solves (factorizations included).
ASSEMBLY_EVENTS = ('pfFunctional', 'pfGradient', 'pfHessian', 'pfMatAssembly')
LINEAR_EVENTS = ('PCSetUp', 'KSPSolve')


def resolved_eps(grid):
    """Smallest eps the grid resolves."""
    return RESOLUTION * spacing_peak(grid.h)


def start_nodes(p, ck, comm):
    """Nodes, nodal phi and multipliers (None, None from a uniform grid) of the
    start: those of the restart checkpoint `ck`, its profile rescaled to -pf_eps,
    or with -pf_adapt its nodes relocated and its phi transferred to them."""
    if ck is None:
        return nodesets.uniform(p.box, p.nodes, half=p.symmetric), None, None
    if ck.symmetric != p.symmetric:
        raise options.UsageError(
            f"-pf_restart {p.restart} holds a {'half' if ck.symmetric else 'full'}-box solution: "
            f"{'add' if ck.symmetric else 'remove'} -pf_symmetric to continue it")
    names = ('nu_area', 'nu_volume', 'nu_moment')[:2 if p.symmetric else 3]
    nu = np.array([ck.attrs.get(k, 0.0) for k in names])
    xy, phi = ck.nodes, ck.phi
    if p.adapt:
        xy, phi = relocated(p, ck, comm)
    return xy, rescaled_phi(phi, float(ck.attrs['eps']), p.eps), nu


def relocated(p, ck, comm):
    """The checkpoint's nodes relocated by CVT (-pf_adapt) and its phi transferred."""
    stage = PETSc.Log.Stage('pfAdapt')
    stage.push()
    beta = locality(ck.nodes, ck.attrs['gamma'], int(ck.attrs.get('spacing_smoothing', 0)),
                    p.plane)
    xy, phi, info = adapt.relocate(comm.tompi4py(), ck.nodes, ck.phi, p.box, beta,
                                   ck.attrs.get('cutoff', p.cutoff), p.adapt, p.plane)
    stage.pop()
    PETSc.Sys.Print(f"adapt: CVT f={p.adapt:g} of {p.restart}: {info['iterations']} Lloyd steps "
                    f"(movement {info['movement']:.1e}), h_min {info['h_min'][0]:.4g} -> "
                    f"{info['h_min'][1]:.4g}, raster {info['raster'][1]}x{info['raster'][0]}, "
                    f"{info['time']:.2f} s")
    return xy, phi


def phase_field_checks(comm, xy, phi, attrs):
    """phi_h one eps inside the box (`limit.boundary_phi`) and, where a level
    set exists, the energy error and level-set distance against the
    sharp-interface shape of the scene and the level set's own energy
    (`limit.level_set_energy`), as checkpoint attributes.

    Collective; rank 0 computes, the others receive.
    """
    result = {}
    if comm.getRank() == 0:
        ckpt = checkpoint.Checkpoint(nodes=xy, phi=phi, attrs=attrs).unfolded()
        field = limit.PhaseField(ckpt)
        result['boundary_phi'] = limit.boundary_phi(ckpt, field=field)
        try:
            c = limit.compare(ckpt, field=field)
            result.update(sharp_energy=c['energy_sharp'], sharp_rel_error=c['rel_error'],
                          sharp_dist_max=c['dist_max'], sharp_dist_mean=c['dist_mean'],
                          level_set_energy=c['energy_level_set'])
        except (ValueError, RuntimeError) as e:
            PETSc.Sys.Print(f"sharp interface: no comparison ({e})", comm=PETSc.COMM_SELF)
    return comm.tompi4py().bcast(result, root=0)


def event_seconds(comm, names, stages):
    """Seconds spent in the named log events during the stages, max over ranks.

    Collective.
    """
    mine = sum(PETSc.Log.Event(name).getPerfInfo(s.id)['time'] for name in names for s in stages)
    return comm.tompi4py().allreduce(mine, op=MPI.MAX)


def run(comm):
    """Collective. Returns the process exit status."""
    opts = PETSc.Options()
    if opts.hasName('help'):
        PETSc.Sys.Print(options.help_text())
        return 0
    p = options.read(opts)
    PETSc.Log.begin()  # event times feed the checkpoint's time split
    t_start = time.perf_counter()
    output = p.output or options.default_output(p)
    size = comm.getSize()
    t0 = time.perf_counter()
    ck = None
    if p.restart:  # -pf_box auto continues in the checkpoint's box
        ck = checkpoint.read(p.restart, comm.tompi4py(),
                             expect_box=None if p.box == 'auto' else p.box)
        p.box = ck.box
    PETSc.Sys.Print(f"pfmembrane: {p.branch} eps={p.eps:g} k={p.k:g} c0={p.c0:g} R={p.radius:g} "
                    f"v={p.reduced_volume:g} box={p.box[0]:g}x{p.box[1]:g} gamma={p.gamma:g} "
                    f"cutoff={p.cutoff:g} quad={p.quad_degree} stage1={p.stage1} ranks={size}"
                    f"{' half box (mirror z=' + format(p.zc, 'g') + ')' if p.symmetric else ''}")

    t_adapt = time.perf_counter()
    xy, phi0, nu0 = start_nodes(p, ck, comm)
    t_adapt = time.perf_counter() - t_adapt if p.adapt else np.nan
    basis_stage = PETSc.Log.Stage('pfBasis')
    basis_stage.push()
    grid = Grid(comm, xy, p.box, p.gamma, p.cutoff, p.quad_degree, p.spacing_smoothing,
                p.plane)
    basis_stage.pop()
    eps_min = resolved_eps(grid)
    under = p.eps < eps_min
    PETSc.Sys.Print(f"grid: {len(xy)} nodes ({grid.layout.nglobal} free), {grid.nquad} quadrature "
                    f"points, eps_min {eps_min:.4g}, set-up {time.perf_counter() - t0:.2f} s")
    if under and not p.force:
        raise options.UsageError(
            f"eps {p.eps:g} is below what this grid resolves (eps_min = {eps_min:.4g}); "
            "use more nodes, an adapted grid, or -pf_force to run anyway")
    basis_stage.push()
    grid.gram  # stage 2 always needs the Hessian: its products are set up with the basis
    basis_stage.pop()
    t_setup = time.perf_counter() - t0

    problem = Problem(grid, p.eps, p.k, p.c0, (p.area, p.volume), p.zc)
    x = problem.create_vec()
    lay = grid.layout
    own = lay.order[lay.start:lay.start + lay.nowned]
    if phi0 is None:
        a, c = options.check_fits(p)
        x.setArray(spheroid_phi(xy[own], a, c, p.zc, p.eps))
    else:
        x.setArray(phi0[own])

    solver = Solver(problem, p)
    # a solved checkpoint's multipliers start stage 1 better than a least-squares fit
    solved_nu = nu0 if ck is not None and ck.attrs.get('converged') else None
    stages = [('pfStage1', lambda v: solver.stage1(v, solved_nu)), ('pfStage2', solver.stage2)]
    if p.stage1 == 'none':
        stages = [('pfStage2', lambda v: solver.stage2_first(v, solved_nu))]
        if nu0 is None:
            solver.evaluate(x)
            nu0 = solver.least_squares_multipliers()
        solver.nu = nu0
    converged, message, status = True, None, 0
    solve_stages = []
    try:
        for name, fn in stages:
            stage = PETSc.Log.Stage(name)
            solve_stages.append(stage)
            stage.push()
            try:
                vals, _ = fn(x)
            finally:
                stage.pop()
            s = solver.stats[name[2:].lower()]
            PETSc.Sys.Print(
                f"{name[2:].lower()}: {s.get('outer', s.get('iterations'))} its"
                f"{' (' + str(s['inner']) + ' inner)' if 'inner' in s else ''}, E {s['energy']:.8f}, "
                f"constraint residual {s['residual']:.2e}, max|phi| {problem.max_abs_phi(x):.4f}, "
                f"{s['time']:.2f} s")
    except (SolveError, Interrupted) as e:
        converged, message = False, str(e)
        status = e.status if isinstance(e, Interrupted) else 1
        vals = problem.gradients(x, solver.gE, solver.gA)

    stage = PETSc.Log.Stage('pfCheckpoint')
    stage.push()
    values = lay.gather(x)
    wall = time.perf_counter() - t_start
    phi_nodes = None
    if comm.getRank() == 0:
        phi_nodes = np.full(len(xy), -1.0)
        phi_nodes[lay.order] = values
    max_phi = problem.max_abs_phi(x)
    attrs = dict(energy=vals[0], area=vals[1], volume=vals[2], moment=vals[3], eps=p.eps,
                 k=p.k, c0=p.c0, gamma=p.gamma, nu_area=solver.nu[0], nu_volume=solver.nu[1],
                 nu_moment=solver.nu[2] if solver.ncon == 3 else 0.0, symmetric=int(p.symmetric),
                 converged=int(converged), wall_time=wall,
                 n_procs=size, cutoff=p.cutoff, quad_degree=p.quad_degree,
                 spacing_smoothing=p.spacing_smoothing,
                 radius=p.radius, reduced_volume=p.reduced_volume, branch=p.branch,
                 under_resolved=int(under), eps_min=eps_min, n_nodes=len(xy), max_phi=max_phi,
                 stage1_iterations=solver.stats.get('stage1', {}).get('inner', -1),
                 stage2_iterations=solver.stats.get('stage2', {}).get('iterations', -1),
                 factorizations=solver.factorizations, adapt=p.adapt, parent=p.restart,
                 time_setup=t_setup, time_adapt=t_adapt,
                 time_stage1=solver.stats.get('stage1', {}).get('time', np.nan),
                 time_stage2=solver.stats.get('stage2', {}).get('time', np.nan),
                 time_assembly=event_seconds(comm, ASSEMBLY_EVENTS, solve_stages),
                 time_linear=event_seconds(comm, LINEAR_EVENTS, solve_stages),
                 peak_rss_mb=comm.tompi4py().allreduce(
                     resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=MPI.MAX))
    if comm.getRank() == 0:
        os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    attrs["box"] = np.asarray(p.box)
    if converged:  # an interrupted run checkpoints at once
        attrs.update(phase_field_checks(comm, xy, phi_nodes, attrs))
    checkpoint.write(output, xy, phi_nodes, attrs, comm=comm.tompi4py())
    stage.pop()
    PETSc.Sys.Print(
        f"result: E {vals[0]:.8f} nu_A {solver.nu[0]:.6g} nu_V {solver.nu[1]:.6g} "
        f"max|phi| {max_phi:.4f} converged {int(converged)}"
        f"{' UNDER-RESOLVED' if under else ''} wall {wall:.2f} s -> {output}")
    if attrs.get("boundary_phi", -1.0) > -1.0 + limit.BOUNDARY_TOL:
        PETSc.Sys.Print(
            f"warning: phi_h reaches {attrs['boundary_phi']:.4f} one eps inside the box edges, "
            f"which hold -1: the box {p.box[0]:g}x{p.box[1]:g} constrains the vesicle "
            "(enlarge -pf_box, or -pf_box auto)")
    if 'sharp_energy' in attrs:
        PETSc.Sys.Print(
            f"sharp interface: E {attrs['sharp_energy']:.6f}, relative error "
            f"{100 * attrs['sharp_rel_error']:+.3f}%, phi_h = 0 within {attrs['sharp_dist_max']:.2e} "
            f"(mean {attrs['sharp_dist_mean']:.2e}) of its curve"
            + (f"; the level set's own energy {attrs['level_set_energy']:.6f} "
               f"({100 * (attrs['level_set_energy'] / attrs['sharp_energy'] - 1):+.4f}%)"
               if np.isfinite(attrs['level_set_energy']) else ""))
    if not converged and comm.getRank() == 0:
        sys.stderr.write(f"pfmembrane: {message} (checkpoint {output} marked converged = 0)\n")
    return status
