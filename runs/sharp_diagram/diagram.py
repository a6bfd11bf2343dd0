"""The sharp reference phase diagram: axisymmetric vesicles of the spontaneous-curvature model
by the project's sharp solver over the atlas's rectangle (c0 -1 ... 2.5, v 0.95 ... 0.55),
the sharp counterpart of the phase-field atlas (runs/atlas/merged/diagram.md).

    python runs/sharp_diagram/diagram.py [--c0 X ...] [--processes 2] [--out runs/sharp_diagram]

From any working directory (--out defaults to this script's folder). The computation of each
c0 row (branch following, step halving, brentq crossings, branch ends; c0 is the phase-field
scene's 2 C0 R, the sharp solver's C0 = c0 / (2 R)) is `pfmembrane.sharp.diagram.row`; this
script runs the rows over a process pool (one row per task, the slow rows first), compares
them with an independent sharp-interface computation and with the atlas, and writes
diagram.md (with `report`'s provenance header), diagram.json and diagram.png into --out.
"""
import argparse
import json
import math
import os
import re
import time
from multiprocessing import Pool

import numpy as np

from pfmembrane import report
from pfmembrane.paper import SCENE
from pfmembrane.sharp import diagram
from pfmembrane.sharp.diagram import DV, JUMP, NECK_ROWS, V_MAX, V_MIN

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
ATLAS = os.path.join(ROOT, 'runs', 'atlas', 'merged', 'diagram.md')
RADIUS = SCENE['radius']
CURVATURES = [-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5]   # reduced c0 = 2 C0 R
# An independent sharp-interface computation of the same model (c0 = 2 C0 R), v high to low:
# (c0, v, branch above, branch below, what it said)
INDEPENDENT = [
    (0.0, 0.5912, None, 'stomatocyte', 'stomatocyte least from 0.5912 down to 0.55 '
                                       '(prolate above)'),
    (-0.5, 0.6906, None, 'stomatocyte', 'stomatocyte below 0.6906'),
    (-1.0, 0.767, None, 'stomatocyte', 'stomatocyte below about 0.767 (neck 0.011-0.04)'),
    (0.5, 0.564, None, 'oblate', 'oblate wins below about 0.564'),
    (2.5, 0.762, 'prolate', 'neck pear', 'prolate above about 0.762, then pears on a '
                                         'narrow-neck branch'),
    (2.5, 0.706, 'neck pear', 'neck dumbbell', 'pears down to about 0.706, narrow-neck '
                                               'dumbbells below'),
    (1.0, None, None, None, 'agrees with the phase-field diagram'),
    (1.5, None, None, None, 'agrees with the phase-field diagram'),
    (2.0, None, None, None, 'agrees with the phase-field diagram'),
]


def row(c0):
    """One row at the scene's radius, with a line of progress as it finishes."""
    result = diagram.row(c0, radius=RADIUS)
    print(f"c0 {c0:g}: {result['wall']:.1f} s, "
          + '; '.join(f"{r['branch']} {r['low']:.3f}-{r['high']:.3f}"
                      for r in result['regions']),
          flush=True)
    return result


# --- the page -------------------------------------------------------------------------------

def atlas_transitions():
    """{c0: [(v, 'a / b'), ...]} of the phase-field diagram (runs/atlas/merged/diagram.md)."""
    found = {}
    try:
        with open(ATLAS) as f:
            for line in f:
                cells = [s.strip() for s in line.strip().strip('|').split('|')]
                if len(cells) == 4 and re.fullmatch(r'-?\d+(\.\d+)?', cells[0]):
                    found[float(cells[0])] = [(float(v), pair) for v, pair in
                                              re.findall(r'(\d\.\d+) \(([^)]*)\)', cells[2])]
    except OSError:
        pass
    return found


def compare(result, v, above, below):
    """The transition of `result` nearest to v into `below` (from `above` when given)."""
    candidates = [t for t in result['transitions'] if t['below'] == below
                  and (above is None or t['above'] == above)]
    if not candidates:
        return None
    return min(candidates, key=lambda t: abs(t['v'] - v))


def fmt(x, digits=4):
    return '-' if x is None or (isinstance(x, float) and math.isnan(x)) else f'{x:.{digits}f}'


def page(results, record, wall, args):
    lines = report.header('The sharp reference phase diagram of the spontaneous-curvature model',
                          record)
    lines += [
        f'Regenerate: `python runs/sharp_diagram/diagram.py` ({wall:.0f} s wall, '
        f'{args.processes} processes).', '',
        'The project\'s sharp solver (`pfmembrane/sharp/solver.py`, its branches followed by '
        '`pfmembrane/sharp/diagram.py`) over the atlas\'s rectangle. '
        'c0 is the phase-field scene\'s 2 C0 R (`analysis.levelset.reference` calls '
        '`sharp.solve(v, branch, c0=c0 / (2 R), radius=R)`); energies in units of k, '
        'E = (k/2) int (H - C0)^2 dA with H = 1/R on a sphere (the sphere at C0 = 0 has 2 pi). '
        f'Every branch is followed in v on a grid of {DV:g} with warm starts (the solver\'s '
        f'`_minimize`, resolution doubled while its spectrum is unresolved), steps halved on '
        f'failure, on leaving the branch or on a jump (a point of the curve moving by more than '
        f'{JUMP:g} R); a branch ends where the step falls below DV / 16. Prolate and oblate: '
        'up-down '
        'symmetric (even modes); stomatocyte, pear and neck pear: all modes. The pear is '
        'switched onto from the prolate at the zero of `sharp.pear_mode` in v; the narrow-neck '
        'branches (c0 = 2.5) start from two spheres joined by a smoothed neck. Least energy '
        'on the v grid; a change of the least branch is solved to 1e-10 in v on the energy '
        'difference (brentq on warm-started minimizations). Neck: the narrowest interior waist '
        'of the generating curve (units of R); gap: z(pi) - z(0), the oblate\'s thickness on '
        'the axis; fold: the least eigenvalue of the second variation on the tangent space '
        'falls towards zero at the end.', '']
    pf = atlas_transitions()
    lines += ['## Summary', '']
    rows = []
    for res in results:
        rows.append([f"{res['c0']:g}",
                     '; '.join(f"{r['branch']} {r['low']:.3f}-{r['high']:.3f}"
                               for r in res['regions']),
                     ', '.join(f"{t['v']:.4f} ({t['above']} / {t['below']})"
                               for t in res['transitions']) or '-',
                     ', '.join(f"{v:.4f} ({p})" for v, p in pf.get(res['c0'], [])) or '-',
                     f"{res['wall']:.0f}"])
    lines += report.table(['c0', 'regions (least energy, v low-high)',
                           'transitions v (above / below)', 'phase field (atlas merged)',
                           'row wall s'], rows)
    lines += ['', '## Against the independent values and the phase-field diagram', '',
              'Independent: a sharp-interface computation of the same model (c0 = 2 C0 R). '
              'Here: the transition of this page into the same branch nearest to the '
              'independent v. Agree: within 0.005 in v.', '']
    rows = []
    for c0, v, above, below, said in INDEPENDENT:
        res = next((r for r in results if r['c0'] == c0), None)
        if res is None:
            continue
        if v is None:
            here = ', '.join(f"{t['v']:.4f} ({t['above']} / {t['below']})"
                             for t in res['transitions']) or 'none'
            theirs = ', '.join(f"{x:.4f} ({p})" for x, p in pf.get(c0, [])) or 'none'
            rows.append([f'{c0:g}', said, '-', here, '-', f'phase field: {theirs}'])
            continue
        t = compare(res, v, above, below)
        if t is None:
            rows.append([f'{c0:g}', said, f'{v:.4f}', f'no transition into {below}', '-',
                         'disagrees'])
            continue
        d = t['v'] - v
        rows.append([f'{c0:g}', said, f'{v:.4f}', f"{t['v']:.4f} ({t['above']} / {t['below']})",
                     f'{d:+.4f}', 'agrees' if abs(d) <= 0.005 else 'disagrees'])
    lines += report.table(['c0', 'independent', 'independent v', 'here', 'here - independent',
                           'within 0.005'], rows)
    for res in results:
        lines += ['', f"## c0 = {res['c0']:g} (row wall {res['wall']:.1f} s)", '']
        lines += report.table(['region: v from', 'to', 'least-energy branch'],
                              [[f"{r['high']:.3f}", f"{r['low']:.3f}", r['branch']]
                               for r in res['regions']])
        lines += ['']
        lines += report.table(['transition v', 'above', 'below', 'E', 'E below - E above',
                               'how'],
                              [[f"{t['v']:.5f}", t['above'], t['below'], fmt(t['E'], 6),
                                '-' if math.isnan(t['E_below']) else
                                f"{t['E_below'] - t['E']:.1e}", t['kind']]
                               for t in res['transitions']]) if res['transitions'] else \
            ['No transition: one branch is least over the whole range.']
        lines += ['']
        rows = []
        for kind, b in res['branches'].items():
            span = (f"{min(b['v']):.4f}-{max(b['v']):.4f}" if b['v'] else '-')
            necks = [x for x in b['neck'] if not math.isnan(x)]
            rows.append([kind, b['start'], span, len(b['v']),
                         (f"{min(necks):.4f}-{max(necks):.4f}" if necks and kind != 'oblate'
                          else '-'),
                         '; '.join(b['ends']) or '-',
                         ', '.join(f"{f['v']:.4f}" for f in b['folds']) or '-'])
        lines += report.table(['branch', 'start', 'v followed', 'points', 'neck range',
                               'ends', 'folds (v)'], rows)
    lines += ['', 'Numbers: diagram.json (per c0, per branch: v, E, multipliers, n, neck, gap, '
              'asymmetry, least eigenvalues, on the v grid or not; regions; transitions). '
              'Figure: diagram.png.', '']
    return lines


def plot(results, path):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    colours = {'prolate': 'tab:blue', 'oblate': 'tab:orange', 'stomatocyte': 'tab:green',
               'pear': 'tab:red', 'neck pear': 'tab:purple', 'neck dumbbell': 'tab:brown'}
    fig = plt.figure(figsize=(15, 7.5))
    grid = fig.add_gridspec(2, 6)
    ax = fig.add_subplot(grid[:, :2])
    for res in results:
        for r in res['regions']:
            ax.barh(res['c0'], r['high'] - r['low'] + DV, left=r['low'] - DV / 2, height=0.4,
                    color=colours.get(r['branch'], 'grey'))
        for t in res['transitions']:
            ax.plot([t['v']] * 2, [res['c0'] - 0.25, res['c0'] + 0.25], 'k-', lw=1)
    for c0, v, _, _, _ in INDEPENDENT:
        if v is not None:
            ax.plot(v, c0 + 0.3, 'kv', ms=5)
    for kind, colour in colours.items():
        ax.barh(math.nan, 0, color=colour, label=kind)
    ax.plot([], [], 'kv', label='independent')
    ax.set(xlabel='v', ylabel='c0 = 2 C0 R', xlim=(V_MAX + DV, V_MIN - DV),
           title='least energy (sharp)')
    ax.legend(fontsize=7, loc='lower left')
    for i, res in enumerate(results[:8]):
        a = fig.add_subplot(grid[i // 4, 2 + i % 4])
        pro = res['branches'].get('prolate', {})
        ref = dict(zip(pro.get('v', []), pro.get('E', [])))
        for kind, b in res['branches'].items():
            pts = [(v, e - ref[v]) for v, e in zip(b['v'], b['E']) if v in ref]
            if pts and kind != 'prolate':
                a.plot(*zip(*pts), '.-', ms=2, lw=1, color=colours[kind], label=kind)
        a.axhline(0, color=colours['prolate'], lw=1)
        a.set_title(f"c0 = {res['c0']:g}: E - E prolate", fontsize=8)
        a.set_xlim(V_MAX, V_MIN)
        a.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def jsonable(x):
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return jsonable(x.item())
    return x


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--c0', type=float, nargs='*', default=CURVATURES)
    ap.add_argument('--processes', type=int, default=2)
    ap.add_argument('--out', default=HERE)
    args = ap.parse_args(argv)
    record = report.provenance()
    start = time.perf_counter()
    # the slow rows first, so that two processes finish together
    order = sorted(args.c0, key=lambda c: -2 * (c in NECK_ROWS) - (c < 0))
    if args.processes > 1:
        with Pool(args.processes) as pool:
            results = pool.map(row, order, chunksize=1)
    else:
        results = [row(c) for c in order]
    results.sort(key=lambda r: r['c0'])
    wall = time.perf_counter() - start
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, 'diagram.md'), 'w') as f:
        f.write('\n'.join(page(results, record, wall, args)) + '\n')
    with open(os.path.join(args.out, 'diagram.json'), 'w') as f:
        json.dump(jsonable(dict(provenance=record, wall=wall, dv=DV, radius=RADIUS,
                                rows=results)), f, indent=1)
    plot(results, os.path.join(args.out, 'diagram.png'))
    print(f'{wall:.0f} s; wrote {args.out}/diagram.md, diagram.json, diagram.png')


if __name__ == '__main__':
    main()
