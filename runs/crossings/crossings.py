"""The two c0 = 0 energy crossings of the spontaneous-curvature phase diagram.

    python runs/crossings/crossings.py [--np 2] [--eps 0.02] [--nodes 40000]
        [--out runs/crossings] [--branch NAME ...] [-- SOLVER OPTIONS]

From any working directory: --out defaults to runs/crossings of the repository.

Seifert, Berndl and Lipowsky (1991): at c0 = 0 the prolate branch has the least energy
above v = 0.652, the oblate one between 0.592 and 0.652, the stomatocyte below 0.592.
Sharp interface (`analysis.sharp`): each crossing v is the root of E_a(v) - E_b(v)
(brentq), at fixed sine resolutions n (both branches at the same n) and at the solver's
default. Phase fields: each branch is followed in v in one process on one grid (`pf.solve`
from the secant predictor of the two states before, Newton on the bordered system first);
the crossing v is the root of a cubic spline through the differences of the level sets' own
Canham-Helfrich energies (`level_set_energy`, the phase field's sharp-limit estimate). The
same spline through the sharp energies at the same v measures what the interpolation alone
errs. A series stops at its first failed solve or level set that is not one sphere (a
stomatocyte whose neck pinched off). Writes OUT/notes.md.
"""
import argparse
import math
import os
import sys
import time
import warnings

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

from pfmembrane import report, series
from pfmembrane.analysis.sizing import required_box, rounded_up
from pfmembrane.paper import SCENE, paper_spacing
from pfmembrane.report import header, iterations, provenance
from pfmembrane.sharp import solver as sharp

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RADIUS = SCENE['radius']
# name: (the branch of least energy above the crossing, the one below, the bracket in v,
# SBL's value)
CROSSINGS = {'prolate-oblate': ('prolate', 'oblate', (0.64, 0.66), 0.652),
             'oblate-stomatocyte': ('oblate', 'stomatocyte', (0.58, 0.60), 0.592)}
# Fixed sine resolutions of the sharp convergence table: the up-down symmetric path
# converges by n = 16, the stomatocyte's neck needs some 200 modes.
RESOLUTIONS = {'prolate-oblate': (8, 12, 16, 32),
               'oblate-stomatocyte': (64, 96, 128, 192, 256)}
XTOL = 1e-7
# Each branch from the first v on: the oblate one thins at the axis and the stomatocyte's
# neck narrows as v falls, so both start where they are widest.
VOLUMES = {'prolate': [round(0.62 + 0.01 * i, 2) for i in range(6)],
           'oblate': [round(0.67 - 0.01 * i, 2) for i in range(11)],
           'stomatocyte': [round(0.62 - 0.01 * i, 2) for i in range(7)]}
MARGIN = 5.0  # eps between every sharp shape and start of a series and the box: 1 + phi < 2e-3
BOX_STEP = 0.01
SPHERE = '1 sphere'


def sharp_energy(v, branch, n=None):
    """E of the sharp branch at v (k = 1, unit R0: the crossings do not depend on R0)."""
    with warnings.catch_warnings():  # the convergence table shows the resolution itself
        warnings.simplefilter('ignore', RuntimeWarning)
        return sharp.solve(v, branch, n=n).energy


def sharp_crossing(name, n=None, xtol=XTOL):
    """v where the two branches of crossing `name` have equal sharp energies."""
    upper, lower, bracket, _ = CROSSINGS[name]
    return brentq(lambda v: sharp_energy(v, upper, n) - sharp_energy(v, lower, n), *bracket,
                  xtol=xtol)


def crossing(vs, upper, lower):
    """Root of the cubic spline through upper - lower at the volumes vs (increasing),
    in the interval where it changes sign; NaN where it does not."""
    d = np.asarray(upper) - np.asarray(lower)
    change = np.flatnonzero(np.sign(d[:-1]) != np.sign(d[1:]))
    if len(vs) < 2 or change.size == 0:
        return math.nan
    i = change[0]
    return brentq(CubicSpline(vs, d), vs[i], vs[i + 1], xtol=XTOL)


def box_of(branch, vs, eps):
    """One box for a series: every sharp shape and start of it with MARGIN eps,
    rounded up to BOX_STEP."""
    need = required_box(branch, vs, eps, RADIUS, margin=MARGIN)[0]
    return rounded_up(need, BOX_STEP)


def follow(branch, vs, args, say):
    """Solve the branch at the volumes vs in order on one grid. Collective."""
    import pfmembrane as pf
    box = box_of(branch, vs, args.eps)
    symmetric = branch != 'stomatocyte'  # the half box holds the up-down symmetric ones
    grid, states, rows = None, [], []
    for v in vs:
        scene = pf.Scene(reduced_volume=v, radius=RADIUS, box=box, branch=branch,
                         symmetric=symmetric)
        # the spacing of args.nodes in the paper box, in every box
        grid = grid or pf.Grid.uniform(scene, nodes=paper_spacing(args.nodes, box))
        say(f"-- {branch}: v {v:g}, box {box[0]:g}x{box[1]:g}{' (half)' if symmetric else ''}")
        t0 = time.perf_counter()
        if states:
            start = (pf.predict(states[-2], states[-1], (v - rows[-1]['v'])
                                / (rows[-1]['v'] - rows[-2]['v'])) if len(states) > 1
                     else states[-1])
            options = dict(args.solver, pf_stage1='none')
        else:  # the sharp shape's profile: on its branch from the first Newton step
            start, options = None, dict(args.solver, pf_start='sharp')
        res = pf.solve(scene, grid, args.eps, start=start, options=options, checks=True)
        rows.append(dict(v=v, attrs=res.attrs, wall=time.perf_counter() - t0))
        say(row(rows[-1]))
        if not res.converged or res.attrs.get('topology') != SPHERE:
            say(f"{branch}: v {v:g} {'is ' + res.attrs.get('topology', 'no level set') if res.converged else 'did not converge (' + res.message + ')'}; the series stops")
            break
        states = (states + [res])[-2:]
    return dict(branch=branch, box=box, symmetric=symmetric,
                nodes=grid.n_nodes if grid else 0, eps_min=grid.eps_min if grid else math.nan,
                rows=rows)


HEADER = ('| v | E | E level set | E sharp | level set vs sharp | topology | nu_A | nu_V '
          '| its (1+2) | s |')


def row(r):
    a = r['attrs']
    if not a.get('converged'):
        return f"| {r['v']:g} | not converged | | | | | | | | {r['wall']:.1f} |"
    its = f"{iterations(a['stage1_iterations'])}+{iterations(a['stage2_iterations'])}"
    level, exact = a.get('level_set_energy', math.nan), a.get('sharp_energy', math.nan)
    return (f"| {r['v']:g} | {a['energy']:.5f} | {level:.5f} | {exact:.5f} "
            f"| {(level - exact) / exact:+.2e} | {a.get('topology', '')} | {a['nu_area']:.4f} "
            f"| {a['nu_volume']:.3f} | {its} | {r['wall']:.1f} |")


def good(series):
    """(v, attrs) of the converged one-sphere states of a series, v increasing."""
    return sorted((r['v'], r['attrs']) for r in series['rows']
                  if r['attrs'].get('converged') and r['attrs'].get('topology') == SPHERE)


def phase_field_crossing(name, series, key):
    """The crossing from attribute `key` of both branches' states at their common v."""
    upper, lower = (dict(good(series[b])) if b in series else {} for b in CROSSINGS[name][:2])
    vs = sorted(set(upper) & set(lower))
    return crossing(vs, [float(upper[v][key]) for v in vs], [float(lower[v][key]) for v in vs])


def sharp_table(say):
    """Crossing v per fixed n and at the default resolution, with seconds. Not collective."""
    table = {}
    for name in CROSSINGS:
        table[name] = []
        for n in RESOLUTIONS[name] + (None,):
            t0 = time.perf_counter()
            table[name].append((n, sharp_crossing(name, n), time.perf_counter() - t0))
            say(f"sharp {name}: n {n or 'default'}: v {table[name][-1][1]:.7f}")
    return table


def shown(path):
    """`path` as a page shows it: relative to the repository when inside it."""
    relative = os.path.relpath(os.path.abspath(path), ROOT)
    return path if relative.startswith(os.pardir) else relative


def write(sharp_rows, series, args, wall, out, record=None):
    """OUT/notes.md, under the provenance `record` (`provenance()`, taken at the start of
    the run; now by default). Not collective."""
    command = (f"python runs/crossings/crossings.py --np {args.np} --eps {args.eps:g} "
               f"--nodes {args.nodes} --out {shown(args.out)}"
               + (f" --branch {' '.join(args.branch)}" if args.branch != list(VOLUMES) else '')
               + (' -- ' + ' '.join(args.options) if args.options else ''))
    lines = [*header("The c0 = 0 energy crossings: prolate-oblate and oblate-stomatocyte",
                     record or provenance()),
             "Seifert, Berndl and Lipowsky (Phys. Rev. A 44, 1182 (1991)): the prolate branch "
             "has the least energy for v above about 0.652, the oblate one between 0.592 and "
             "0.652, the stomatocyte below 0.592. Method in the docstring of "
             "`runs/crossings/crossings.py`.\n",
             f"Regenerate: `{command}` (`make crossings`). {args.np} MPI ranks on "
             f"{os.cpu_count()} cores, shared with another 2-rank job; wall time {wall:.0f} s.\n",
             "## Sharp interface\n",
             "Root of E_a(v) - E_b(v) by brentq (xtol 1e-7) with `analysis.sharp.solve` at the "
             "highest sine mode n of the tangent angle (even modes only, the up-down symmetric "
             "path, for the oblate and prolate branches; all modes and the closure constraint "
             "for the stomatocyte), both branches at the same n; default: the solver's own "
             "(n doubled from 32, or 64 for the stomatocyte, until the top quarter of the "
             "spectrum is below 1e-6). The crossing v depends on no length.\n",
             "| crossing | n | v | change from the n before | s |", "|---|---|---|---|---|"]
    for name, rows in sharp_rows.items():
        before = None
        for n, v, seconds in rows:
            change = '' if before is None else f"{v - before:+.1e}"
            lines.append(f"| {name} | {n or 'default'} | {v:.6f} | {change} | {seconds:.1f} |")
            before = v
    lines += ["", "## Phase fields\n",
              f"eps {args.eps:g}, uniform grids of the spacing of {args.nodes} nodes in the paper "
              f"box (1.5 x 2), R = {RADIUS:g}, k = 1, C0 = 0; each box holds every sharp shape and "
              f"start of its series with {MARGIN:g} eps to spare. The first state starts from the "
              "sharp shape's tanh profile (`-pf_start sharp`), each next one from the secant "
              "predictor of the two before (from the one before at the second), straight to "
              "stage 2. E: the phase field's energy; E level set: the Canham-Helfrich energy of "
              "phi_h = 0 (`level_set_energy`); E sharp: `analysis.sharp` at the same v; "
              "topology: of phi_h = 0 (must be one sphere).\n"]
    for s in series.values():
        lines += [f"### {s['branch']}\n",
                  f"Box {s['box'][0]:g} x {s['box'][1]:g}{', solved on its half z >= Zb/2' if s['symmetric'] else ''}, "
                  f"{s['nodes']} nodes, eps_min {s['eps_min']:.4g}.\n",
                  HEADER, '|' + '---|' * (HEADER.count('|') - 1)]
        lines += [row(r) for r in s['rows']] + ['']
    lines += ["## The crossings\n",
              "Roots of the cubic spline through the energy differences at the v both branches "
              "reached as one sphere. The sharp energies at the same v through the same spline "
              "give the interpolation's own error (against the sharp root above).\n",
              "| crossing | SBL | sharp (default n) | phase field, level-set E | minus SBL "
              "| phase field, E | sharp E at the same v, spline |",
              "|---|---|---|---|---|---|---|"]
    for name, (_, _, _, published) in CROSSINGS.items():
        level = phase_field_crossing(name, series, 'level_set_energy')
        lines.append(f"| {name} | {published} | {sharp_rows[name][-1][1]:.6f} | {level:.4f} "
                     f"| {level - published:+.4f} "
                     f"| {phase_field_crossing(name, series, 'energy'):.4f} "
                     f"| {phase_field_crossing(name, series, 'sharp_energy'):.6f} |")
    report.write(os.path.join(out, 'notes.md'), lines)


def main(argv=None):
    record = provenance()  # before anything is measured
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog='python runs/crossings/crossings.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2, help='MPI ranks')
    ap.add_argument('--eps', type=float, default=0.02)
    ap.add_argument('--nodes', type=int, default=40000, help='nodes in the paper box (scaled)')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'crossings'))
    ap.add_argument('--branch', nargs='+', default=list(VOLUMES), choices=list(VOLUMES))
    ap.add_argument('options', nargs='*', metavar='-- OPTION')
    args = ap.parse_args(argv)
    args.solver = {k.lstrip('-'): v for k, v in zip(args.options[::2], args.options[1::2])}
    series.ensure_ranks(args.np, __file__, argv)
    import pfmembrane as pf
    PETSc = pf.petsc(sys.argv[:1])
    say = PETSc.Sys.Print
    t0 = time.perf_counter()
    branches = {b: follow(b, VOLUMES[b], args, say) for b in args.branch}
    if PETSc.COMM_WORLD.getRank() == 0:
        sharp_rows = sharp_table(say)
        os.makedirs(args.out, exist_ok=True)
        write(sharp_rows, branches, args, time.perf_counter() - t0, args.out, record)
        print(os.path.join(args.out, 'notes.md'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
