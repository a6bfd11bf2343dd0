"""The application: options -> scene, grid and start -> `api.solve` -> checkpoint."""
import os
import sys
import time

import numpy as np
from petsc4py import PETSc

from pfmembrane import api
from pfmembrane.analysis.limit import BOUNDARY_TOL
from pfmembrane.io import options


def start_of(p, comm):
    """The restart's result (None for a fresh start) and the scene, whose
    box is the checkpoint's on a restart and `auto` sized for a fresh one."""
    if not p.restart:
        scene = api.Scene(p.reduced_volume, p.c0, p.radius, p.k, p.box, p.branch, p.symmetric)
        scene = scene.sized(p.eps)
        options.check_fits(scene, p.eps)
        return None, scene
    # -pf_box auto continues in the checkpoint's box
    start = api.read(p.restart, comm, expect_box=None if p.box == 'auto' else p.box)
    return start, api.Scene(p.reduced_volume, p.c0, p.radius, p.k,
                            tuple(start.attrs['box']), p.branch, p.symmetric)


def grid_of(p, scene, start, comm):
    """The uniform grid of -pf_nodes, the restart's nodes, or with -pf_adapt
    those nodes relocated by CVT; the basis parameters are the options'."""
    params = dict(gamma=p.gamma, cutoff=p.cutoff, quad_degree=p.quad_degree,
                  spacing_smoothing=p.spacing_smoothing, comm=comm)
    if start is None:
        return api.Grid.uniform(scene, p.nodes, **params)
    half = bool(start.attrs.get('symmetric', 0))
    if half != p.symmetric:
        raise options.UsageError(
            f"-pf_restart {p.restart} holds a {'half' if half else 'full'}-box solution: "
            f"{'add' if half else 'remove'} -pf_symmetric to continue it")
    if p.adapt:
        return api.adapt(start, p.adapt, **params)
    return api.Grid(scene, start.nodes, **params)


def run(comm):
    """Collective. Returns the process exit status."""
    opts = PETSc.Options()
    if opts.hasName('help'):
        PETSc.Sys.Print(options.help_text())
        return 0
    p = options.read(opts)
    t_start = time.perf_counter()
    output = p.output or options.default_output(p)
    start, scene = start_of(p, comm)
    PETSc.Sys.Print(f"pfmembrane: {p.branch} eps={p.eps:g} k={p.k:g} c0={p.c0:g} R={p.radius:g} "
                    f"v={p.reduced_volume:g} box={scene.box[0]:g}x{scene.box[1]:g} "
                    f"gamma={p.gamma:g} cutoff={p.cutoff:g} quad={p.quad_degree} "
                    f"stage1={p.stage1} ranks={comm.getSize()}"
                    f"{' half box (mirror z=' + format(scene.zc, 'g') + ')' if p.symmetric else ''}")
    grid = grid_of(p, scene, start, comm)
    t_setup = time.perf_counter() - t_start
    d = grid.discrete
    PETSc.Sys.Print(f"grid: {grid.n_nodes} nodes ({d.layout.nglobal} free), {d.nquad} quadrature "
                    f"points, eps_min {grid.eps_min:.4g}, set-up {t_setup:.2f} s")
    res = api.solve(scene, grid, p.eps, start=start, prefix='')
    # The run's own clocks: reading the restart and adapting count too.
    res.attrs.update(wall_time=time.perf_counter() - t_start, time_setup=t_setup,
                     parent=p.restart)
    if comm.getRank() == 0:
        os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    stage = PETSc.Log.Stage('pfCheckpoint')
    stage.push()
    res.save(output)
    stage.pop()
    summary(res, output)
    if not res.converged and comm.getRank() == 0:
        sys.stderr.write(f"pfmembrane: {res.message} (checkpoint {output} marked converged = 0)\n")
    return res.status


def summary(res, output):
    """The result line, and the box and sharp-interface lines where they apply."""
    a = res.attrs
    PETSc.Sys.Print(
        f"result: E {a['energy']:.8f} nu_A {a['nu_area']:.6g} nu_V {a['nu_volume']:.6g} "
        f"max|phi| {a['max_phi']:.4f} converged {a['converged']}"
        f"{' UNDER-RESOLVED' if a['under_resolved'] else ''} wall {a['wall_time']:.2f} s "
        f"-> {output}")
    if a.get("boundary_phi", -1.0) > -1.0 + BOUNDARY_TOL:
        box = a['box']
        PETSc.Sys.Print(
            f"warning: phi_h reaches {a['boundary_phi']:.4f} one eps inside the box edges, "
            f"which hold -1: the box {box[0]:g}x{box[1]:g} constrains the vesicle "
            "(enlarge -pf_box, or -pf_box auto)")
    if 'sharp_energy' in a:
        PETSc.Sys.Print(
            f"sharp interface: E {a['sharp_energy']:.6f}, relative error "
            f"{100 * a['sharp_rel_error']:+.3f}%, phi_h = 0 within {a['sharp_dist_max']:.2e} "
            f"(mean {a['sharp_dist_mean']:.2e}) of its curve"
            + (f"; the level set's own energy {a['level_set_energy']:.6f} "
               f"({100 * (a['level_set_energy'] / a['sharp_energy'] - 1):+.4f}%)"
               if np.isfinite(a['level_set_energy']) else ""))
