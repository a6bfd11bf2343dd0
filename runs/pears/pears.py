"""The pear bifurcation of the prolate as eps falls, against the sharp limit:

    python runs/pears/pears.py [--np 2] [--v 0.8] [--out runs/pears] [--force]
    python runs/pears/pears.py --sharp [--out runs/pears]

From any working directory: --out defaults to runs/pears of the repository.

At each (eps, nodes) of ROWS: the full-box prolate at reduced volume v from its sharp shape
at the row's c0 = 2 C0 R, followed up in C0 (`pf.continuation`) to its first index change
without a fold (`branching.bifurcation`, bracketed twice with steps 4 times shorter), its
first fold or C_TO, then along the critical mode (`switch`): the pears, for up to STEPS
points. Where the corrector itself lands on a pear near the pitchfork (its level set
up-down asymmetric, `branching.asymmetric`; the subcritical pears turn back in c0, so the
step reads as a fold) the pears are followed on from that point. Either way until
their level set has no energy for `branching.OTHER_TOPOLOGY` points (a bud off:
`branching.topology_lost`) or c0 leaves [C_LOW, C_TO]. The box is the atlas's for its
pear family at c0 = C_TO (runs/atlas: `BOX`). The sharp pear bifurcation D_pe at the same
v is the zero of the sharp prolate's least up-down antisymmetric second variation (`sharp.pear_bifurcation`), and
`--sharp` tabulates that line over v (OUT/sharp.md); the report fits D(eps) = D_0 + C eps^2
to the uniform rows' bifurcations and compares D_0 with it. Writes OUT/pears_v<v>.md; each eps's
route is kept in OUT/pears_v<v>_eps<eps>[_adapted][_gamma<gamma>].json and reused unless --force.
"""
import argparse
import dataclasses
import itertools
import json
import math
import os
import sys
import time

import numpy as np

from pfmembrane import series
from pfmembrane.report import header, provenance
from pfmembrane.analysis.sizing import branch_box
from pfmembrane.paper import SCENE

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RADIUS = SCENE['radius']
# (eps, nodes, eps of the uniform grid whose solution the CVT adapts to or None, start c0,
# max-ent gamma); eps / h about 1.8 on the uniform grids; the later rows start nearer the
# bifurcation the earlier ones predict. With gamma 0.8 the adapted grids hold the pear mode
# off (runs/pears/README.md), as the paper's sequences lower gamma on adapted grids.
G = 0.8  # `pf.Grid`'s gamma
ROWS = [(0.04, 6124, None, 2.5, G), (0.03, 12000, None, 2.5, G),
        (0.02, 25000, None, 2.5, G), (0.015, 45000, None, 3.3, G),
        (0.02, 40000, 0.02, 3.3, G), (0.01, 40000, 0.02, 3.5, G),
        (0.01, 40000, 0.02, 3.5, 0.4)]
ADAPT_F = 100.0  # density 1 + f |grad phi_h|
C_TO, C_LOW = 4.5, 1.5   # reduced c0 = 2 C0 R
DS, STEPS = 0.1, 40                    # step in reduced c0; points on the pear branch
# The box: the full-box prolate's sharp shapes at C_TO at 9 volumes from 0.55 to 0.95 (the
# atlas's range of v) with 5 eps to spare, rounded up to 0.05: the atlas's pear box.
BOX = dict(volumes=np.linspace(0.55, 0.95, 9), margin=5.0, step=0.05)
SHARP_V = (0.71, 0.72, 0.73, 0.74, 0.75, 0.8, 0.85, 0.9)


def sharp_line(vs=SHARP_V):
    """(v, reduced c0 of D_pe) of the sharp prolate, from a scan in c0 by 0.1 from 1.5 to
    8 and `sharp.pear_bifurcation` on the first sign change; nan where there is none."""
    from pfmembrane.sharp import solver as sharp
    line = []
    for v in vs:
        grid = np.arange(1.5, 8.0 + 1e-9, 0.1)
        values = [sharp.pear_mode(v, c / (2 * RADIUS), RADIUS)[0] for c in grid]
        change = next((i for i in range(1, len(grid)) if values[i - 1] > 0 >= values[i]), None)
        line.append((v, math.nan if change is None else 2 * RADIUS * sharp.pear_bifurcation(
            v, (grid[change - 1] / (2 * RADIUS), grid[change] / (2 * RADIUS)), RADIUS)))
    return line


def state(res):
    """What a row keeps of a point; the asymmetry and level-set energy from phi_h = 0."""
    from pfmembrane.analysis import levelset
    a = res.attrs
    curve = levelset.level_set(res.checkpoint().unfolded())
    return dict(c0=2 * RADIUS * float(a['c0']), E=float(a['energy']),
                level=float(a.get('level_set_energy', math.nan)), nu_A=float(a['nu_area']),
                nu_V=float(a['nu_volume']), index=int(a.get('index_0', -1)),
                fold=int(a.get('fold', 0)), topology=str(a.get('topology', 'none')),
                asymmetry=levelset.up_down_asymmetry(curve, RADIUS) if curve else math.nan,
                its=int(a.get('stage2_iterations', -1)), converged=int(a['converged']))


def route(eps, nodes, coarse, c_from, gamma, v, say):
    """The prolate at v followed in C0 from c_from to its bifurcation, and the pears
    switched to from there; on the uniform grid of `nodes`, or on that grid relocated by
    CVT to the solution at eps `coarse` (at c_from) on the half box and unfolded, so that
    the grid keeps the up-down symmetry (the full-box CVT does not: its prolate is up-down
    asymmetric, runs/pears/README.md). Collective."""
    import pfmembrane as pf
    from pfmembrane.branching import asymmetric, bifurcation, topology_lost
    from pfmembrane.paper import paper_spacing
    t0 = time.perf_counter()
    box = branch_box('prolate', BOX['volumes'], eps, RADIUS, C_TO / (2 * RADIUS),
                     margin=BOX['margin'], step=BOX['step'])
    scene = pf.Scene(reduced_volume=v, c0=c_from / (2 * RADIUS), radius=RADIUS, box=box,
                     branch='prolate', symmetric=False)
    if coarse:  # adapted on the half box, unfolded: an up-down symmetric full-box grid
        half = dataclasses.replace(scene, symmetric=True)
        start = pf.solve(half, pf.Grid.uniform(half, nodes=paper_spacing(nodes, box),
                                               gamma=gamma), coarse,
                         options={'pf_start': 'sharp'}, checks=True)
        unfolded = pf.solve(half, pf.adapt(start, ADAPT_F, gamma=gamma), eps,
                            start=start, checks=True).unfolded()
        grid = pf.Grid.of(unfolded)
        # a converged state on these nodes, but for the cells at the plane: Newton alone
        start = pf.solve(scene, grid, eps, start=unfolded, options={'pf_stage1': 'none'}, checks=True)
    else:
        grid = pf.Grid.uniform(scene, nodes=paper_spacing(nodes, box), gamma=gamma)
        start = pf.solve(scene, grid, eps, options={'pf_start': 'sharp'}, checks=True)
    say(f"-- eps {eps:g}: box {box[0]:g}x{box[1]:g}, {grid!r}")
    ds = DS / (2 * RADIUS)
    folds = []

    def note(text):
        say(f"   prolate {text}")
        if text.endswith(' fold'):
            folds.append(text)

    res, reached, jumped = bifurcation(
        start, 'c0', ds, STEPS, C_TO / (2 * RADIUS), say=note, through_folds=False,
        left=asymmetric, scale=2 * RADIUS)
    out = dict(eps=eps, nodes=grid.n_nodes, adapted=coarse or 0, box=list(box), v=v,
               start=c_from, gamma=gamma,
               reached=2 * RADIUS * reached, bifurcation=math.nan, eigenvalue=math.nan,
               jumped=int(jumped), pears=[])
    out['prolate_end'] = 'fold' if folds else ('C_TO' if reached >= C_TO / (2 * RADIUS)
                                               else 'corrector')
    if res is None:
        say(f"-- eps {eps:g}: no index change without a fold up to c0 {out['reached']:.4f}"
            " (a fold or C_TO)")
        return dict(out, wall=time.perf_counter() - t0)
    out['bifurcation'] = 2 * RADIUS * reached
    say(f"-- eps {eps:g}: the prolate bifurcates near c0 {out['bifurcation']:.4f}"
        + (", where its corrector left it for a pear: followed on from there" if jumped else ''))
    if jumped:  # on the pears already, going the way the corrector went
        pears = itertools.chain([res], pf.continuation(
            res, 'c0', math.copysign(ds, res.attrs['dp_ds']), STEPS - 1, checks=True))
    else:
        pears = pf.continuation(res, 'c0', ds, STEPS, switch=True, checks=True)
    for p in pears:
        out['eigenvalue'] = float(res.attrs.get('critical_eigenvalue', math.nan))
        s = state(p)
        out['pears'].append(s)
        say(f"   pear c0 {s['c0']:.4f} E {s['E']:.6f} level {s['level']:.6f} index "
            f"{s['index']} {s['topology']} asymmetry {s['asymmetry']:+.4f} its {s['its']}")
        if not C_LOW <= s['c0'] <= C_TO or topology_lost([q['topology'] for q in out['pears']]):
            break
    return dict(out, wall=time.perf_counter() - t0)


def events(points):
    out, before = [], None
    for p in points:
        e = ['fold'] if p['fold'] else []
        if before is not None and before['index'] != p['index'] and not p['fold']:
            e.append('index change')
        if before is not None and before['topology'] != p['topology']:
            e.append(f"topology {before['topology']} -> {p['topology']}")
        out.append(', '.join(e))
        before = p
    return out


def extrapolate(rows):
    """(D_0, C, largest residual) of the least-squares fit D(eps) = D_0 + C eps^2 to the
    bifurcations of the uniform-grid rows, or None with fewer than two."""
    pts = [(r['eps'], r['bifurcation']) for r in rows
           if math.isfinite(r['bifurcation']) and not r['adapted']]
    if len(pts) < 2:
        return None
    eps, d = np.array(pts).T
    a = np.stack([np.ones_like(eps), eps ** 2], axis=1)
    (d0, c), *_ = np.linalg.lstsq(a, d, rcond=None)
    return d0, c, float(np.abs(a @ (d0, c) - d).max())


def report(rows, v, line, record=None):
    """The lines of OUT/pears_v<v>.md, under the provenance `record` (`provenance()`,
    taken at the start of the run; now by default)."""
    d_pe = dict(line).get(v, math.nan)
    lines = [*header(f"The pear bifurcation of the prolate at v = {v:g}, in c0 = 2 C0 R",
                     record or provenance()),
             f"{rows[0]['ranks']} MPI ranks, {os.cpu_count()} cores. Regenerate: "
             f"`python runs/pears/pears.py --v {v:g}` (`runs/pears/pears.py`).",
             '', f"Sharp D_pe at v = {v:g}: c0 = {d_pe:.5f} (`sharp.pear_bifurcation`).", '',
             '| eps | nodes | gamma | box | from c0 | prolate to c0 | ends | bifurcation c0 | '
             'vs sharp | critical eigenvalue | pear points | pear fold c0 | wall s |',
             '|' + '---|' * 13]
    for r in rows:
        folds = [p['c0'] for p in r['pears'] if p['fold']]
        lines.append(
            f"| {r['eps']:g} | {r['nodes']}{' adapted' if r['adapted'] else ''} | "
            f"{r['gamma']:g} | "
            f"{r['box'][0]:g} x {r['box'][1]:g} | {r['start']:g} | "
            f"{r['reached']:.4f} | {'on a pear' if r.get('jumped') else r.get('prolate_end', '')} | "
            f"{r['bifurcation']:.4f} | "
            f"{r['bifurcation'] - d_pe:+.4f} | {r['eigenvalue']:.2e} | {len(r['pears'])} | "
            f"{', '.join(f'{c:.4f}' for c in folds) or '-'} | {r['wall']:.1f} |")
    fit = extrapolate(rows)
    if fit:
        d0, c, worst = fit
        lines += ['', "Fit of the uniform grids' bifurcations to D_0 + C eps^2 (`extrapolate`): "
                  f"D_0 = {d0:.4f} ({d0 - d_pe:+.4f}, {(d0 - d_pe) / d_pe:+.2%} against the "
                  "sharp D_pe), "
                  f"C = {c:.1f}, largest residual {worst:.4f}."]
    for r in rows:
        if not r['pears']:
            continue
        lines += ['', f"## Pears at eps {r['eps']:g} ({r['nodes']} nodes)", '',
                  '| c0 | E | E level set | nu_A | nu_V | index | topology | asymmetry | '
                  'events | converged | its |', '|' + '---|' * 11]
        for p, e in zip(r['pears'], events(r['pears'])):
            lines.append(f"| {p['c0']:.4f} | {p['E']:.6f} | {p['level']:.6f} | "
                         f"{p['nu_A']:.4f} | {p['nu_V']:.3f} | {p['index']} | {p['topology']} "
                         f"| {p['asymmetry']:+.4f} | {e} | {p['converged']} | {p['its']} |")
    return lines


def main(argv=None):
    record = provenance()  # before anything is measured
    ap = argparse.ArgumentParser(prog='python runs/pears/pears.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--v', type=float, default=0.8)
    ap.add_argument('--eps', type=float, nargs='+',
                    help='the rows of ROWS to run (all); the report has every row on record')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'pears'))
    ap.add_argument('--force', action='store_true')
    ap.add_argument('--sharp', action='store_true', help='the sharp D_pe line only')
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    if args.sharp:
        t0 = time.perf_counter()
        line = sharp_line()
        text = [*header('The sharp pear bifurcation D_pe of the prolate', record),
                'Regenerate: `python runs/pears/pears.py --sharp` '
                f"({time.perf_counter() - t0:.1f} s, one process).", '',
                '| v | c0 = 2 C0 R of D_pe |', '|---|---|'] + \
            [f"| {v:g} | {c:.5f} |" for v, c in line]
        with open(os.path.join(args.out, 'sharp.md'), 'w') as f:
            f.write('\n'.join(text) + '\n')
        print('\n'.join(text))
        return 0
    series.ensure_ranks(args.np, __file__, sys.argv[1:])
    import pfmembrane as pf
    from mpi4py import MPI
    pf.petsc(sys.argv[:1])
    root = MPI.COMM_WORLD.Get_rank() == 0

    def say(text):
        if root:
            print(text, flush=True)

    rows = []
    for eps, nodes, coarse, c_from, gamma in ROWS:
        path = os.path.join(args.out, f"pears_v{args.v:g}_eps{eps:g}"
                            f"{'_adapted' if coarse else ''}"
                            f"{'' if gamma == G else f'_gamma{gamma:g}'}.json")
        chosen = not args.eps or any(math.isclose(eps, e) for e in args.eps)
        if os.path.exists(path) and not (chosen and args.force):
            with open(path) as f:
                rows.append(json.load(f))
            continue
        if not chosen:
            continue
        row = dict(route(eps, nodes, coarse, c_from, gamma, args.v, say),
                   ranks=MPI.COMM_WORLD.Get_size())
        if root:
            with open(path, 'w') as f:
                json.dump(row, f, indent=1)
        rows.append(row)
    if root:
        text = report(rows, args.v, sharp_line([args.v]), record)
        with open(os.path.join(args.out, f"pears_v{args.v:g}.md"), 'w') as f:
            f.write('\n'.join(text) + '\n')
        print('\n'.join(text))
    return 0


if __name__ == '__main__':
    sys.exit(main())
