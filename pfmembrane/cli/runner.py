"""One run of the application's options (`io.options.Params`): its scene,
start, grid and solve through the API, and its checkpoint.

The command line runs one; a study runs many in one process with a `Cache`,
so that a step on the grid of an earlier step reuses that grid (its basis,
operators and partition) and starts from its result in memory. Public for
studies, with the helpers that read a sequence of options files (`steps_of`,
`option_of`, `output_of`, `converged`).
"""
import glob
import os
import re
import sys
import time
import warnings
from dataclasses import dataclass, field, fields

import h5py
import numpy as np

import pfmembrane as pf
from pfmembrane.io import checkpoint, options
from pfmembrane.starts import check_fits


@dataclass
class Cache:
    """Results by checkpoint path and uniform grids by their parameters."""
    results: dict = field(default_factory=dict)
    grids: dict = field(default_factory=dict)


def start_of(p, comm, cache, start=None):
    """The restart's result (None for a fresh start; `start` in its place when
    given) and the scene, whose box is the checkpoint's on a restart and `auto`
    sized for a fresh start."""
    if not p.restart:
        scene = pf.Scene(p.reduced_volume, p.c0, p.radius, p.k, p.box, p.branch, p.symmetric,
                         p.harmonics, p.dihedral, p.mirror)
        scene = scene.sized(p.eps)
        check_fits(scene, p.eps)
        return None, scene
    start = start or cache.results.get(os.path.abspath(p.restart))
    if start is None or (p.box != 'auto' and not np.allclose(start.attrs['box'], p.box)):
        # -pf_box auto continues in the checkpoint's box
        start = pf.read(p.restart, comm, expect_box=None if p.box == 'auto' else p.box)
    half = bool(start.attrs.get('symmetric', 0))
    if half != p.symmetric:
        raise options.UsageError(
            f"-pf_restart {p.restart} holds a {'half' if half else 'full'}-box solution: "
            f"{'add' if half else 'remove'} -pf_symmetric to continue it")
    return start, pf.Scene(p.reduced_volume, p.c0, p.radius, p.k,
                           tuple(start.attrs['box']), p.branch, p.symmetric, p.harmonics,
                           p.dihedral, p.mirror)


def grid_of(p, scene, start, comm, cache):
    """The uniform grid of -pf_nodes, the restart's nodes, or with -pf_adapt
    those nodes relocated by CVT; the basis parameters are the options'. A
    grid already built for the same nodes and parameters is reused."""
    params = dict(gamma=p.gamma, cutoff=p.cutoff, quad_degree=p.quad_degree,
                  spacing_smoothing=p.spacing_smoothing, spacing_floor=p.spacing_floor,
                  partition=p.partition)
    if start is not None and p.adapt:
        return pf.adapt(start, p.adapt, comm=comm, band=p.adapt_band, **params)
    if start is not None:
        if start.grid is not None and start.grid.params == params and start.grid.fits(scene):
            return start.grid
        return pf.Grid(scene, start.nodes, comm=comm, **params)
    key = (scene.box, scene.symmetric, p.nodes, tuple(sorted(params.items())))
    if key not in cache.grids:
        cache.grids[key] = pf.Grid.uniform(scene, p.nodes, comm=comm, **params)
    return cache.grids[key]


def execute(p, comm, print_fn, solve_options=None, prefix=None, cache=None, start=None,
            modes_options=None):
    """Solve the run of `p` and write its checkpoint, with the phase-field
    checks and, with -pf_modes, the stability. Collective.

    `solve_options` (command-line names without the dash) go to the solve
    under `prefix` (by default one of its own), `modes_options` to the mode
    analysis; the solve prints a line per stage. `start` (a `Result`, such as
    `pf.predict`'s) replaces the restart's own. Returns (result, checkpoint
    path).
    """
    cache = cache if cache is not None else Cache()
    t_start = time.perf_counter()
    output = p.output or options.default_output(p)
    start, scene = start_of(p, comm, cache, start)
    print_fn(f"pfmembrane: {p.branch} eps={p.eps:g} k={p.k:g} c0={p.c0:g} R={p.radius:g} "
             f"v={p.reduced_volume:g} box={scene.box[0]:g}x{scene.box[1]:g} "
             f"gamma={p.gamma:g}{f' floor={p.spacing_floor:g}' if p.spacing_floor else ''} "
             f"cutoff={p.cutoff:g} quad={p.quad_degree} "
             f"stage1={p.stage1} ranks={comm.getSize()}"
             f"{' half box (mirror z=' + format(scene.zc, 'g') + ')' if p.symmetric else ''}")
    grid = grid_of(p, scene, start, comm, cache)
    fresh = grid.setup_pending
    if fresh and grid.adapt_info:
        print_fn(grid.adapt_summary())
    t_setup = time.perf_counter() - t_start
    d = grid.discrete
    print_fn(f"grid: {grid.n_nodes} nodes ({d.layout.nglobal} free), {d.nquad} quadrature "
             f"points, eps_min {grid.eps_min:.4g}, set-up {t_setup:.2f} s"
             f"{'' if fresh else ' (grid reused)'}")
    with warnings.catch_warnings():
        # the run's summary says each once, on rank 0 (`summary`): a saddle, a change of
        # topology; unused options are errors of their own (`-options_left`)
        warnings.simplefilter('ignore', UserWarning)
        res = pf.solve(scene, grid, p.eps, start=start,
                       options={**(solve_options or {}), 'pf_summary': True}, prefix=prefix,
                       checks=True)
    if p.modes >= 0 and res.converged:
        pf.stability(res, p.modes, options=modes_options, prefix=prefix)
    # The run's own clocks: reading the restart and adapting count too.
    res.attrs.update(wall_time=time.perf_counter() - t_start, time_setup=t_setup,
                     parent=p.restart)
    if comm.getRank() == 0:
        os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    stage = pf.petsc().Log.Stage('pfCheckpoint')
    stage.push()
    try:
        res.save(output)
    finally:
        stage.pop()
    cache.results[os.path.abspath(output)] = res
    return res, output


# Invalid input of an options file or line (the application's exit status 2): raised
# by `run_files` before any checkpoint is written. A checkpoint that cannot be read (by
# `pf.read`, or as a run's restart) raises CheckpointError, also exit status 2.
UsageError = options.UsageError
CheckpointError = checkpoint.CheckpointError


def run_files(*paths, args=(), comm=None, print_fn=None, cache=None, start=None):
    """`execute` the run of the options files `paths` (later ones override earlier
    ones) with the command-line `args` after them, passing their solver options
    (`solver_options`) to the solve; `comm` defaults to PETSc's COMM_WORLD, `print_fn`
    to its Sys.Print. Collective. Returns (result, checkpoint path); raises
    `UsageError` for invalid input."""
    PETSc = pf.petsc()
    table = options.Table.from_files(*paths, args=args)
    return execute(options.read(table), comm or PETSc.COMM_WORLD, print_fn or PETSc.Sys.Print,
                   solver_options(table), prefix=None, cache=cache, start=start)


def solved(scene_file, args, path, cache, print_fn=None):
    """The result of the options file `scene_file` with `args` added and
    `-pf_output path`: read back if `path` exists, else solved on COMM_WORLD
    and summarized. Collective."""
    if os.path.exists(path):
        return pf.read(path)
    PETSc = pf.petsc()
    print_fn = print_fn or PETSc.Sys.Print
    table = options.Table.from_files(scene_file, args=[*args, '-pf_output', path])
    res, _ = execute(options.read(table), PETSc.COMM_WORLD, print_fn, solver_options(table),
                     prefix=None, cache=cache)
    summary(res, path, print_fn)
    return res


def solver_options(table):
    """The entries of an options table that belong to a solve: the solver's
    own `-pf_` settings and every PETSc option."""
    own = {'pf_' + f.name for f in fields(options.Settings)}
    return {k: v for k, v in table.items() if not k.startswith('pf_') or k in own}


def summary(res, output, print_fn):
    """The result line, and the box, topology, sharp-interface and stability
    lines where they apply; a topology other than the start's is flagged."""
    from pfmembrane.analysis.levelset import BOUNDARY_TOL
    a = res.attrs
    print_fn(
        f"result: E {a['energy']:.8f} nu_A {a['nu_area']:.6g} nu_V {a['nu_volume']:.6g} "
        f"max|phi| {a['max_phi']:.4f} converged {a['converged']}"
        f"{' UNDER-RESOLVED' if a['under_resolved'] else ''} wall {a['wall_time']:.2f} s "
        f"-> {output}")
    if a.get("boundary_phi", -1.0) > -1.0 + BOUNDARY_TOL:
        box = a['box']
        print_fn(
            f"warning: phi_h reaches {a['boundary_phi']:.4f} one eps inside the box edges, "
            f"which hold -1: the box {box[0]:g}x{box[1]:g} constrains the vesicle "
            "(enlarge -pf_box, or -pf_box auto)")
    if a.get('saddle'):
        print_fn(f"warning: a SADDLE: the solve returned to the axisymmetric state, unstable "
                 f"to m = {', '.join(map(str, a['start_unstable_m']))} (see -pf_perturb, "
                 "-pf_stage1_rtol)")
    if 'sharp_note' in a:
        print_fn(f"sharp interface: {a['sharp_note']}")
    if 'topology' in a:
        before = a.get('start_topology', '')
        print_fn(f"topology: phi_h = 0 is {a['topology']}"
                 + (f" (CHANGED: the start was {before})" if before and before != a['topology']
                    else ''))
    if 'torus_radii' in a:
        tube, centre = a['torus_radii']
        print_fn(f"level set: a torus of tube radius {tube:.4g} round r = {centre:.4g} "
                 f"(ratio {centre / tube:.4f}), its own energy {a['level_set_energy']:.6f}")
    if 'level_set_shift' in a:  # the 3D surface of a field with harmonics
        print_fn(f"level set (3D): genus {a['genus']:g}, its energy on the constraints "
                 f"{a['level_set_energy']:.6f} +- {a['level_set_error']:.1e} (moved along its "
                 f"normal by at most {a['level_set_shift']:.3g} to the scene's reduced volume; "
                 "NaN: no such move)")
    elif 'component_energies' in a:
        parts = ' + '.join(f"{e:.6f}" for e in a['component_energies'])
        print_fn(f"level set: its own energy {a['level_set_energy']:.6f}, the sum over its "
                 f"{len(a['component_energies'])} components ({parts})")
    elif 'sharp_energy' not in a and 'torus_radii' not in a and 'level_set_energy' in a:
        print_fn(f"level set: its own energy {a['level_set_energy']:.6f} (no sharp shape of "
                 "this scene to compare)")
    if 'sharp_energy' in a:
        print_fn(
            f"sharp interface: E {a['sharp_energy']:.6f}, relative error "
            f"{100 * a['sharp_rel_error']:+.3f}%, phi_h = 0 within {a['sharp_dist_max']:.2e} "
            f"(mean {a['sharp_dist_mean']:.2e}) of its curve"
            + (f"; the level set's own energy {a['level_set_energy']:.6f} "
               f"({100 * (a['level_set_energy'] / a['sharp_energy'] - 1):+.4f}%)"
               if np.isfinite(a['level_set_energy']) else ""))
    if 'index_m' in a:
        unstable = [m for m, i in enumerate(a['index_m']) if i > 0]
        print_fn(f"stability: index per m = 0..{len(a['index_m']) - 1}: "
                 f"{' '.join(map(str, a['index_m']))}, lowest eigenvalues "
                 f"{' '.join(format(v, '.4g') for v in a['lowest_m'])} "
                 + (f"(UNSTABLE to m = {', '.join(map(str, unstable))})" if unstable
                    else "(stable)") + f", {a['time_modes']:.2f} s")


def option_of(step, name):
    """The last value an options file gives -name, or None."""
    with open(step) as f:
        found = re.findall(rf'^\s*-{name}\s+(\S+)', f.read(), flags=re.M)
    return found[-1] if found else None


def steps_of(directory):
    """The step options files of a sequence directory, in run order."""
    steps = sorted(glob.glob(os.path.join(directory, '*.opts')))
    if not steps:
        sys.exit(f"{directory}: no options files")
    return steps


def output_of(step):
    """The -pf_output path an options file names."""
    out = option_of(step, 'pf_output')
    if out is None:
        sys.exit(f"{step}: names no -pf_output")
    return out


def converged(path):
    try:
        with h5py.File(path, 'r') as f:
            return bool(f.attrs['converged'])
    except (OSError, KeyError):
        return False
