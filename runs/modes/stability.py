"""Azimuthal stability along branches: the index per mode m of every state.

    python runs/modes/stability.py [--np 2] [--groups 1] [--eps 0.04] [--nodes 6124]
        [--modes 6] [--out runs/modes] [--series NAME ...] [--count K] [--values X ...]
        [--box Rb,Zb] [-- SOLVER OPTIONS]

Each series is a continuation in one process on one grid (`pf.solve` from the previous
state, Newton on the bordered system first), and at each converged state `pf.stability`:
the index per m = 0 ... M (negative eigenvalues of the second variation in psi(r, z)
cos(m theta), rigid motions excluded) and the lowest eigenvalue per m. A series stops at
its first failed solve. The series (`SERIES`): the prolate, oblate and stomatocyte branches
at c0 = 0 for v = 0.95 ... 0.55, and the oblate branch in the reduced spontaneous curvature
c0 = 2 C0 R = 0 ... 2.5 at v = 0.8, 0.7, 0.6, and in v at c0 = 2.8 (pde2path's vesicle demo); `--count K` keeps the first K points of each, `--values X ...` replaces their values.
Writes OUT/branches.md (one table per series, headed by the provenance of the measurement:
`report.provenance`) and OUT/branches.png (the lowest eigenvalue of m = 2, 3, 4 along each
series); OUT defaults to runs/modes of the repository, whatever the working directory.

The series are independent: `--groups G` splits the NP ranks into G groups of NP / G ranks,
each following every G-th series on its own sub-communicator, so one `mpiexec -n NP` keeps
every rank busy; the tables are the same whatever the grouping.
"""
import argparse
import math
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.analysis.sizing import default_box, required_box
from pfmembrane.paper import paper_spacing
from pfmembrane import series as launch
from pfmembrane.report import iterations

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

RADIUS = 0.4
VOLUMES = [round(0.95 - 0.05 * i, 2) for i in range(9)]
CURVATURES = [0.0, 0.5, 1.0, 1.5, 2.0, 2.5]   # reduced c0 = 2 C0 R
# name: (branch, the parameter followed, its values, the other parameter's value)
SERIES = {
    'prolate': ('prolate', 'v', VOLUMES, 0.0),
    'oblate': ('oblate', 'v', VOLUMES, 0.0),
    'stomatocyte': ('stomatocyte', 'v', VOLUMES, 0.0),
    **{f"oblate_v{v:g}": ('oblate', 'c0', CURVATURES, v) for v in (0.8, 0.7, 0.6)},
    # pde2path's vesicle demo follows the oblate branch in v at its c0 = C0 R = 1.4 (its
    # energy int (H - c0)^2 dA, H the mean curvature, on the unit sphere): SBL's 2.8
    'oblate_c2.8': ('oblate', 'v', VOLUMES, 2.8),
}
MARGIN = 3.0  # eps between every shape of a series and the box


def scenes(name, values=None):
    """(reduced volume, reduced c0) of each point of a series (`values` in place of its
    own values of the parameter it follows)."""
    _, parameter, own, other = SERIES[name]
    return [(x, other) if parameter == 'v' else (other, x) for x in values or own]


def box_of(branch, points, eps):
    """One box for a series: every sharp shape and start of it with MARGIN eps."""
    need = np.max([required_box(branch, [v], eps, RADIUS, c0 / (2 * RADIUS), margin=MARGIN)[0]
                   for v, c0 in points], axis=0)
    return default_box(tuple(need))


def follow(name, args, comm, say):
    """Solve and analyse the points of one series in order. Collective on `comm`."""
    branch = SERIES[name][0]
    points = scenes(name, args.values)[:args.count]
    box = args.box or box_of(branch, points, args.eps)
    grid, previous, rows = None, None, []
    for v, c0 in points:
        scene = pf.Scene(reduced_volume=v, c0=c0 / (2 * RADIUS), radius=RADIUS, box=box,
                         branch=branch)
        # the paper box's spacing in every box
        grid = grid or pf.Grid.uniform(scene, nodes=paper_spacing(args.nodes, box),
                                       comm=comm)
        say(f"-- {name}: v {v:g} c0 {c0:g} (C0 {scene.c0:g}), box {box[0]:g}x{box[1]:g}")
        t0 = time.perf_counter()
        options = dict(args.solver, **({'pf_stage1': 'none'} if previous else {}))
        res = pf.solve(scene, grid, args.eps, start=previous, options=options, checks=True)
        if not res.converged:
            say(f"{name}: v {v:g} c0 {c0:g} did not converge ({res.message}); the series stops")
            rows.append(dict(v=v, c0=c0, attrs=res.attrs, wall=time.perf_counter() - t0))
            break
        pf.stability(res, args.modes)
        rows.append(dict(v=v, c0=c0, attrs=res.attrs, wall=time.perf_counter() - t0))
        say(row(rows[-1]))
        previous = res
    return dict(name=name, branch=branch, box=box, nodes=grid.n_nodes if grid else 0, rows=rows)


HEADER = ('| v | c0 | E | nu_A | nu_V | E level set | topology | its (1+2) | index per m '
          '| lowest eigenvalue per m | modes s | s |')


def row(r):
    a = r['attrs']
    if not a.get('converged'):
        return f"| {r['v']:g} | {r['c0']:g} | not converged | | | | | | | | | {r['wall']:.1f} |"
    its = f"{iterations(a['stage1_iterations'])}+{iterations(a['stage2_iterations'])}"
    level = a.get('level_set_energy', math.nan)
    return (f"| {r['v']:g} | {r['c0']:g} | {a['energy']:.5f} | {a['nu_area']:.4f} "
            f"| {a['nu_volume']:.3f} | {level:.5f} | {a.get('topology', '')} | {its} "
            f"| {' '.join(map(str, a['index_m']))} "
            f"| {' '.join(format(x, '.3g') for x in a['lowest_m'])} "
            f"| {a['time_modes']:.1f} | {r['wall']:.1f} |")


def shown(path):
    """`path` as a page names it: relative to the repository root when inside it."""
    path = os.path.abspath(path)
    return os.path.relpath(path, ROOT) if os.path.commonpath([path, ROOT]) == ROOT else path


def write(results, args, out, record):
    """OUT/branches.md, headed by the provenance `record` (`report.provenance`), and
    OUT/branches.png. Not collective."""
    lines = ['\n'.join(report.header('Azimuthal stability along branches', record)),
             f"eps {args.eps:g}, uniform grids of the spacing of {args.nodes} nodes in the paper box, R = {RADIUS:g}, "
             f"m = 0 ... {args.modes}, {args.np} MPI ranks in {args.groups} group(s) on "
             f"{os.cpu_count()} cores. "
             "c0 is the reduced spontaneous curvature 2 C0 R (SBL's). index per m: negative "
             "eigenvalues of the second variation of E - nu . (c - c0) in the mode "
             "psi(r, z) cos(m theta) (on the constraints' tangent space for m = 0), rigid "
             "motions excluded; lowest eigenvalue per m: the least non-rigid one.\n",
             f"Regenerate: `python runs/modes/stability.py --np {args.np} --eps "
             f"{args.eps:g} --nodes {args.nodes} --modes {args.modes} --out {shown(args.out)}"
             + (f" --series {' '.join(args.series)}" if args.series != list(SERIES) else '')
             + (f" --count {args.count}" if args.count else '')
             + (f" --values {' '.join(map(format, args.values))}" if args.values else '')
             + (f" --box {args.box[0]:g},{args.box[1]:g}" if args.box else '')
             + "`.\n"]
    for s in results:
        lines += [f"\n## {s['name']}: the {s['branch']} branch, {SERIES[s['name']][1]} "
                  f"followed\n", f"Box {s['box'][0]:g} x {s['box'][1]:g}, {s['nodes']} nodes.\n",
                  HEADER, '|' + '---|' * (HEADER.count('|') - 1)] + [row(r) for r in s['rows']]
    report.write(os.path.join(out, 'branches.md'), lines)
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for s in results:
        kind = SERIES[s['name']][1]
        ax = axes[0 if kind == 'v' else 1]
        done = [r for r in s['rows'] if r['attrs'].get('converged')]
        x = [r['v'] if kind == 'v' else r['c0'] for r in done]
        for m, style in ((2, '-'), (3, '--'), (4, ':')):
            if done and len(done[0]['attrs']['lowest_m']) > m:
                ax.plot(x, [r['attrs']['lowest_m'][m] for r in done], style, marker='o',
                        label=f"{s['name']} m = {m}")
    for ax, label in zip(axes, ('reduced volume v (c0 = 0)', 'reduced c0 = 2 C0 R')):
        ax.axhline(0.0, color='k', linewidth=0.8)
        ax.set_yscale('symlog', linthresh=1.0)
        ax.set_xlabel(label)
        ax.set_ylabel('lowest eigenvalue of mode m')
        if ax.lines:
            ax.legend(fontsize=7)
    fig.savefig(os.path.join(out, 'branches.png'), dpi=130, bbox_inches='tight')
    plt.close(fig)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog='python runs/modes/stability.py',
                                 description=__doc__.splitlines()[0])
    launch.group_arguments(ap, 'series')
    launch.grid_arguments(ap, 0.04, 6124, 'series (default: the paper box, grown where needed)')
    ap.add_argument('--modes', type=int, default=6, help='highest m')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'modes'),
                    help='directory of the table and figure (default: runs/modes of the repository)')
    ap.add_argument('--series', nargs='+', default=list(SERIES), choices=list(SERIES))
    ap.add_argument('--count', type=int, help='the first COUNT points of each series')
    ap.add_argument('--values', type=float, nargs='+',
                    help="the followed parameter's values, in place of each series' own")
    args = launch.parsed(ap, argv)
    launch.ensure_ranks(args.np, __file__, argv)
    record = report.provenance()   # before the measurement (and before MPI starts)
    results = launch.on_groups(args.np, args.groups, __file__,
                               args.series, lambda name, comm, say: follow(name, args, comm, say))
    if results is not None:
        os.makedirs(args.out, exist_ok=True)
        write(results, args, args.out, record)
        print(os.path.join(args.out, 'branches.md'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
