"""The phase-field phase diagram of the spontaneous-curvature model, by accuracy on demand,
beside the sharp reference diagram (runs/sharp_diagram/diagram.json).

    mpiexec -n 2 python runs/phase_diagram/diagram.py [--tol 3e-3] [--budget 120]
        [--max-nodes 25000] [--c0 X ...] [--until HH:MM] [--fresh] [--page-only]
        [--out runs/phase_diagram]

Every point (c0, v, family) is `pf.accurate` from the scene alone (`-pf_box auto`, the
half box for the up-down symmetric prolate and oblate), TOL --tol, at most --budget s and
--max-nodes nodes a point; c0 is the reduced 2 C0 R (R 0.4). The points: v = 0.55, 0.60,
..., 0.95 on every row, the prolate and the oblate at each, the stomatocyte and the pear
(`-pf_branch pear`) where the sharp diagram has that branch, and both sides of every sharp
crossing at its v +- BRACKET. Each phase-field state is named by the sharp branch it is: the
sharp branches its start can reach (`OWN`) at that v, the nearest in energy, when within
MATCH (relative, or three error bars) of the phase-field estimate; else 'unmatched'.

At each grid v the least of the resolved states (TOL reached, matched) against the sharp
diagram's least branch; where the sharp least branch's state did not resolve, the row says
what stopped it (its smallest feature, the eps and nodes reached). Each sharp crossing is
located in the phase field by the zero of the two states' estimate difference (linear
between the nearest points on either side) and compared within WITHIN in v.

Each rank is a worker that solves one point at a time on its own (COMM_SELF), taking the
next point nobody holds, the longest first (by an earlier points.json's walls), so the ranks
end together. The points are small, so two ranks on one point run well short of twice as
fast as one: two points side by side end more points an hour than one point on two ranks.

Every point is kept in points.json the moment it ends (under a lock on points.json.lock: the
ranks share one machine) and a later call with the same commit, TOL, budget, node cap and
number of workers goes on from them (--fresh: start over); the page (diagram.md, with
provenance) and the figure (diagram.png) are written at the end, or from points.json alone
by --page-only (no PETSc).
"""
import argparse
import contextlib
import fcntl
import json
import math
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.series import seconds_left
from pfmembrane.sharp.diagram import stored_energy

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
SHARP = os.path.join(ROOT, 'runs', 'sharp_diagram', 'diagram.json')
R = 0.4
CURVATURES = [-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5]
GRID = [round(0.55 + 0.05 * i, 2) for i in range(9)]
BRACKET = 0.01          # the crossing's points on either side, in v
BRACKET_TOL = 1e-3      # their TOL at most, lower where the crossing is shallow (`bracket_tol`)
TOL_FLOOR = 1e-4        # and at least
WITHIN = 0.005          # a transition agrees within this in v
MATCH = 0.005           # a state is a sharp branch within this relative energy (or 3 bars)
SYMMETRIC = ('prolate', 'oblate')
# the sharp branches each phase-field start can become
OWN = {'prolate': ('prolate', 'neck dumbbell'), 'oblate': ('oblate',),
       'stomatocyte': ('stomatocyte',), 'pear': ('neck pear',)}
START = {'prolate': 'prolate', 'oblate': 'oblate', 'stomatocyte': 'stomatocyte',
         'neck pear': 'pear', 'neck dumbbell': 'prolate'}


# --- the sharp diagram ----------------------------------------------------------------------

class Sharp:
    """One row of the sharp diagram: its branches' E(v), regions and transitions."""

    def __init__(self, row):
        self.row = row
        self.c0 = row['c0']
        self.regions = row['regions']
        self.transitions = row['transitions']

    def energy(self, name, v):
        """The branch's energy at v (the neck pear: where it is a pear), NaN outside it."""
        return stored_energy(self.row, name, v, asymmetric=name == 'neck pear')

    def least(self, v):
        """The least-energy branch at grid v."""
        for r in self.regions:
            if r['low'] - 1e-9 <= v <= r['high'] + 1e-9:
                return r['branch']
        return None

    def crossings(self):
        return [t for t in self.transitions if t['kind'] == 'crossing']

    def families(self, v):
        """The phase-field starts to solve at v: prolate and oblate, and those whose sharp
        branch exists there."""
        found = ['prolate', 'oblate']
        for start in ('stomatocyte', 'pear'):
            if any(math.isfinite(self.energy(b, v)) for b in OWN[start]):
                found.append(start)
        return found


# --- one point ------------------------------------------------------------------------------

def solve_point(c0, v, family, tol, budget, args):
    """The record of `pf.accurate` on (c0, v, family) to `tol` within `budget` s: every
    attribute the page needs."""
    budget = min(budget, seconds_left(args.until) - 10.0)
    record = {'c0': c0, 'v': v, 'family': family, 'tol': tol}
    if budget < 10.0:
        return {**record, 'status': 'skipped (deadline)', 'wall': 0.0}
    scene = pf.Scene(reduced_volume=v, c0=c0 / (2 * R), radius=R, box='auto', branch=family,
                     symmetric=family in SYMMETRIC)
    t0 = time.perf_counter()
    try:
        res = pf.accurate(scene, tol, max_time=budget, max_nodes=args.max_nodes,
                          comm=pf.petsc().COMM_SELF)
    except Exception as exc:  # a refused first step, a start that fails: the point's result
        message = ' '.join(str(exc).split())
        return {**record, 'status': f"failed: {type(exc).__name__}: {message}",
                'wall': time.perf_counter() - t0}
    a = res.attrs
    floats = lambda key: [float(x) for x in a[key]] if key in a else []  # noqa: E731
    return {**record, 'status': 'reached' if int(a.get('tol_reached', 0)) else 'not reached',
            'wall': time.perf_counter() - t0, 'estimate': float(a.get('sharp_estimate', math.nan)),
            'bar': float(a.get('sharp_error', math.nan)), 'eps': floats('tol_eps'),
            'nodes': [int(n) for n in floats('tol_nodes')], 'features': floats('tol_features'),
            'feature_kind': str(a.get('tol_feature_kind', '')),
            'closing': float(a.get('tol_closing', math.nan)),
            'follows': float(a.get('tol_follows', math.nan)),
            'stop': str(a.get('tol_stop', '')), 'topology': res.topology or 'none'}


def name_state(p, sharp):
    """(sharp branch, its energy, relative difference) the point is, or ('unmatched', ...)."""
    e = p.get('estimate', math.nan)
    if not math.isfinite(e):
        return 'unmatched', math.nan, math.nan
    near = [(abs(e / sharp.energy(b, p['v']) - 1), b, sharp.energy(b, p['v']))
            for b in OWN[p['family']] if math.isfinite(sharp.energy(b, p['v']))]
    if not near:
        return 'unmatched', math.nan, math.nan
    d, b, es = min(near)
    bar = p.get('bar', math.nan)
    if d <= MATCH or (math.isfinite(bar) and abs(e - es) <= 3 * bar):
        return b, es, e / es - 1
    return 'unmatched', es, e / es - 1


def resolved(p):
    """A state the diagram uses: a sharp branch, with an error bar (TOL reached or not: its
    bar decides), its smallest feature not held at the interface width."""
    return (p.get('status') in ('reached', 'not reached')
            and p.get('state') not in (None, 'unmatched')
            and math.isfinite(p.get('bar', math.nan)) and not math.isfinite(p.get('follows', math.nan)))


def why(p):
    """What stopped an unresolved point, in a few words."""
    if p['status'].startswith(('failed', 'skipped')):
        return p['status']
    feats = [f for f in p.get('features', []) if math.isfinite(f)]
    parts = [p['status'], f"topology {p.get('topology')}"]
    if feats:
        parts.append(f"smallest feature {feats[-1]:.3g}" + (
            f" ({p['feature_kind']})" if p.get('feature_kind') else ''))
    if p.get('eps'):
        parts.append(f"eps to {p['eps'][-1]:.3g} on {p['nodes'][-1]} nodes")
    if math.isfinite(p.get('follows', math.nan)):
        parts.append(f"held at the interface width (following eps like eps^{p['follows']:.2f})")
    if math.isfinite(p.get('closing', math.nan)):
        parts.append(f"a limit shape (closing like eps^{p['closing']:.2f})")
    if p.get('state') == 'unmatched' and math.isfinite(p.get('relative', math.nan)):
        parts.append(f"estimate {100 * p['relative']:+.1f}% from the nearest sharp branch")
    if p.get('stop'):
        parts.append(p['stop'])
    return '; '.join(parts)


# --- the diagram ----------------------------------------------------------------------------

def bracket_tol(sharp, t):
    """TOL of a crossing's points: an error of TOL E in the difference of the two states
    moves the crossing by TOL E / |d(E below - E above)/dv|, kept under WITHIN / 2 (the
    slope the sharp row's), between TOL_FLOOR and BRACKET_TOL."""
    gap = lambda v: sharp.energy(t['below'], v) - sharp.energy(t['above'], v)  # noqa: E731
    slope = abs(gap(t['v'] + BRACKET) - gap(t['v'] - BRACKET)) / (2 * BRACKET)
    return min(BRACKET_TOL, max(TOL_FLOOR, 0.5 * WITHIN * slope / abs(t['E'])))


def row_points(sharp, tol, budget):
    """(v, family, TOL, budget) of a row: the grid, then the crossings' brackets (twice
    the budget)."""
    points = [(v, f, tol, budget) for v in GRID for f in sharp.families(v)]
    for t in sharp.crossings():
        for v in (round(t['v'] - BRACKET, 4), round(t['v'] + BRACKET, 4)):
            for b in (t['above'], t['below']):
                points.append((v, START[b], bracket_tol(sharp, t), 2 * budget))
    return points


def least_rows(sharp, points):
    """The page's rows of the least state at every grid v."""
    rows = []
    for v in GRID:
        here = [p for p in points if abs(p['v'] - v) < 1e-9]
        good = [p for p in here if resolved(p)]
        best = min(good, key=lambda p: p['estimate']) if good else None
        want = sharp.least(v)
        if best is not None and best['state'] == want:
            verdict = 'agrees'
        else:
            theirs = [p for p in here if p.get('state') == want and resolved(p)]
            reach = [p for p in here if p['family'] == START.get(want, '')]
            if not theirs and reach:
                verdict = f"not resolved: the {want} ({why(reach[0])})"
            elif best is None:
                verdict = 'not resolved: no state reached TOL'
            elif theirs and (theirs[0]['estimate'] - best['estimate']
                             <= theirs[0]['bar'] + best['bar']):
                verdict = (f"undecided at this TOL: the {want} "
                           f"{theirs[0]['estimate'] - best['estimate']:.3g} above the "
                           f"{best['state']}, within their bars ({best['bar']:.2g}, "
                           f"{theirs[0]['bar']:.2g})")
            else:
                gap = theirs[0]['estimate'] - best['estimate'] if theirs else math.nan
                verdict = (f"DISAGREES: {best['state']} below the {want} by {gap:.4g} "
                           f"(bars {best['bar']:.2g}, {theirs[0]['bar']:.2g})" if theirs else
                           f"DISAGREES: {best['state']} least, the {want} not computed")
        cells = '; '.join(
            f"{p['family']}: {p['estimate']:.5f} +- {p['bar']:.1g} ({p.get('state')})"
            if resolved(p) else f"{p['family']}: -" for p in here)
        rows.append([f"{v:.2f}", want or '-', best['state'] if best else '-', verdict, cells])
    return rows


def crossing_rows(sharp, points):
    """The page's rows of the sharp crossings located in the phase field."""
    rows, found = [], []
    for t in sharp.crossings():
        a, b = t['above'], t['below']
        by_v = {}
        for p in points:
            if resolved(p) and p['state'] in (a, b):
                by_v.setdefault(p['v'], {})[p['state']] = (p['estimate'], p['bar'])
        vs = sorted(v for v, d in by_v.items() if a in d and b in d and abs(v - t['v']) < 0.06)
        brackets = [v for v in vs if abs(abs(v - t['v']) - BRACKET) < 1e-4]
        if len(brackets) == 2:  # the crossing's own points, to their tighter TOL
            vs = brackets
        diff = [by_v[v][b][0] - by_v[v][a][0] for v in vs]
        bars = [by_v[v][b][1] + by_v[v][a][1] for v in vs]
        cross = [i for i in range(len(vs) - 1)
                 if diff[i] * diff[i + 1] <= 0 and diff[i] != diff[i + 1]]
        if cross:
            def located(i):
                slope = (diff[i + 1] - diff[i]) / (vs[i + 1] - vs[i])
                return vs[i] - diff[i] / slope, max(bars[i], bars[i + 1]) / abs(slope)
            v_pf, v_bar = min((located(i) for i in cross), key=lambda c: abs(c[0] - t['v']))
            verdict = 'agrees' if abs(v_pf - t['v']) <= WITHIN else 'DISAGREES'
            found.append((sharp.c0, v_pf, a, b))
            rows.append([f"{sharp.c0:g}", f"{a} / {b}", f"{t['v']:.4f}",
                         f"{v_pf:.4f} +- {v_bar:.2g}", f"{v_pf - t['v']:+.4f}", verdict,
                         ' '.join(f"{v:.4f}: {d:+.4f}" for v, d in zip(vs, diff))])
        else:
            miss = [p for p in points if abs(p['v'] - t['v']) <= BRACKET + 1e-9
                    and p['family'] in (START[a], START[b]) and not resolved(p)]
            rows.append([f"{sharp.c0:g}", f"{a} / {b}", f"{t['v']:.4f}", '-', '-',
                         'not located: ' + ('; '.join(f"{p['family']} at v {p['v']:.4f}: "
                                                      f"{why(p)}" for p in miss)
                                            or 'no sign change of the difference'),
                         ' '.join(f"{v:.4f}: {d:+.4f}" for v, d in zip(vs, diff)) or '-'])
    return rows, found


COLOURS = {'prolate': 'tab:blue', 'oblate': 'tab:orange', 'stomatocyte': 'tab:green',
           'neck pear': 'tab:red', 'neck dumbbell': 'tab:purple'}


def figure(path, sharps, points, found):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(9.5, 5))
    for sharp in sharps:
        for r in sharp.regions:
            ax.plot([r['low'], r['high']], [sharp.c0 - 0.12] * 2, lw=4,
                    color=COLOURS.get(r['branch'], 'k'), solid_capstyle='butt')
        for t in sharp.transitions:
            ax.plot([t['v']] * 2, [sharp.c0 - 0.25, sharp.c0 + 0.25], 'k-', lw=1)
        mine = [p for p in points if p['c0'] == sharp.c0]
        for v, _, least, verdict, _ in least_rows(sharp, mine) if mine else []:
            y = sharp.c0 + 0.08
            if verdict == 'agrees':
                ax.plot(float(v), y, 'o', color=COLOURS.get(least, 'k'), ms=8)
            elif verdict.startswith('undecided'):
                ax.plot(float(v), y, 's', color='0.6', ms=7)
            elif verdict.startswith('DISAGREES'):
                ax.plot(float(v), y, 'o', color=COLOURS.get(least, 'k'), ms=8, mec='r', mew=2.5)
            else:
                ax.plot(float(v), y, 'x', color='k', ms=9)
    for c0, v, a, b in found:
        ax.plot(v, c0 + 0.08, 'kd', ms=5)
    for name, colour in COLOURS.items():
        ax.plot([], [], 'o', color=colour, label=name)
    ax.plot([], [], 's', color='0.6', label='undecided within the bars')
    ax.plot([], [], 'o', color='w', mec='r', mew=2.5, label='disagrees')
    ax.plot([], [], 'kx', label="sharp least state not resolved")
    ax.plot([], [], 'kd', label='phase-field crossing')
    ax.set_xlabel('reduced volume v')
    ax.set_ylabel('c0 = 2 C0 R')
    ax.set_title('phase field (markers: the least state where resolved) over the sharp '
                 'diagram (bars: least branch; lines: transitions)', fontsize=9)
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def page(args, record, sharps, points, wall):
    lines = report.header('The phase-field phase diagram, by accuracy on demand', record)
    if args.page_only:
        now = report.provenance()
        lines += [f"This page and the figure rewritten from points.json (no solve) by "
                  f"`{now['command']}` at commit `{now['commit']}`.", '']
    times = [p['wall'] for p in points]
    lines += [f"Every point `pf.accurate` from the scene alone on one rank, {args.workers} points "
              "at a time (each rank of the run a worker taking the next point): TOL "
              f"{args.tol:g} at the grid points, at most {args.budget:g} s and {args.max_nodes} nodes a point, "
              "`-pf_box auto` (the half box for the prolate and the oblate); c0 = 2 C0 R, "
              f"R {R}. {len(points)} points, their walls summing to {sum(times):.0f} s; "
              f"the calls that solved them took {wall:.0f} s ({wall / 60:.1f} min) in all; "
              f"{np.median(times) if times else 0:.1f} s the median point, "
              f"{max(times) if times else 0:.0f} s the longest. The sharp diagram: "
              "runs/sharp_diagram/diagram.md. A state is the sharp branch its start can reach "
              f"nearest in energy within {MATCH:g} relative (or three error bars). 'Resolved': "
              "matched, with an error bar (TOL reached or not: the bar decides), its smallest "
              "feature not held at the interface width; a grid point is undecided where two "
              "states lie within their bars.", '',
              "![diagram](diagram.png)", '', '## Crossings', '',
              "The sharp crossing against the zero of the phase-field estimates' difference "
              "(E below - E above, linear between the crossing's two points when both "
              "resolved, else between the resolved points either side); its bar in v the "
              "two states' error bars over the difference's slope; agrees within "
              f"{WITHIN:g} in v. The points at v = sharp v +- {BRACKET:g} are solved to "
              f"TOL = 0.5 x {WITHIN:g} x |slope| / E of the sharp row, between {TOL_FLOOR:g} "
              f"and {BRACKET_TOL:g} (`bracket_tol`), with twice the budget.", '']
    rows, found = [], []
    for sharp in sharps:
        r, f = crossing_rows(sharp, [p for p in points if p['c0'] == sharp.c0])
        rows += r
        found += f
    verdicts = [row[3].split(':')[0] for sharp in sharps
                for row in least_rows(sharp, [p for p in points if p['c0'] == sharp.c0])]
    counts = {v: verdicts.count(v) for v in dict.fromkeys(verdicts)}
    agree = [row[4] for row in rows if row[5] == 'agrees']
    lines[lines.index('![diagram](diagram.png)'):lines.index('![diagram](diagram.png)')] = [
        f"Summary: of {len(verdicts)} grid points ({len(sharps)} rows of {len(GRID)} v), "
        + ', '.join(f"{n} {v}" for v, n in counts.items())
        + f"; of {len(rows)} sharp crossings {len(found)} located, {len(agree)} within "
        f"{WITHIN:g} in v ({', '.join(agree) or 'none'}).", '']
    lines += report.table(['c0', 'above / below', 'sharp v', 'phase field v +- bar', 'difference',
                           'verdict', 'E below - E above at v'], rows)
    for sharp in sharps:
        mine = [p for p in points if p['c0'] == sharp.c0]
        if not mine:
            continue
        lines += ['', f"## c0 = {sharp.c0:g}", '']
        lines += report.table(['v', 'sharp least', 'phase-field least', 'verdict',
                               'resolved estimates (state)'], least_rows(sharp, mine))
        lines += ['']
        lines += report.table(
            ['v', 'start', 'TOL', 'status', 'estimate', 'bar', 'state', 'vs sharp', 'eps', 'nodes',
             'wall s', 'what stopped it'],
            [[f"{p['v']:.4f}", p['family'], f"{p['tol']:.2g}", p['status'].split(':')[0],
              f"{p.get('estimate', math.nan):.6f}", f"{p.get('bar', math.nan):.2g}",
              p.get('state', '-'), f"{100 * p.get('relative', math.nan):+.3f}%",
              ' '.join(f"{e:.3g}" for e in p.get('eps', [])) or '-',
              ' '.join(str(n) for n in p.get('nodes', [])) or '-', f"{p['wall']:.1f}",
              '-' if resolved(p) else why(p)]
             for p in sorted(mine, key=lambda p: (p['v'], p['family']))])
    report.write(os.path.join(args.out, 'diagram.md'), lines)
    figure(os.path.join(args.out, 'diagram.png'), sharps, points, found)


class Store:
    """points.json, shared by the workers (one machine): the points done and the points
    claimed, read and rewritten under an exclusive lock on points.json.lock, so each worker takes
    the next point nobody holds and a point is kept the moment it ends."""

    def __init__(self, path, key, record):
        self.path, self.key, self.record = path, key, record

    @contextlib.contextmanager
    def locked(self):
        with open(self.path + '.lock', 'a') as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            try:
                yield self._read()
            finally:
                fcntl.flock(lock, fcntl.LOCK_UN)

    def _read(self):
        if os.path.exists(self.path):
            with open(self.path) as f:
                return json.load(f)
        return {'key': self.key, 'record': self.record, 'points': [], 'claimed': []}

    def _write(self, kept):
        with open(self.path + '.new', 'w') as f:
            json.dump(kept, f)
        os.replace(self.path + '.new', self.path)

    def start(self, fresh):
        """Keep the points of an earlier call with the same key unless `fresh`; no claims.
        Returns the walls of the points found, at any key ({ident: s}: `schedule`'s)."""
        with self.locked() as kept:
            prior = {ident(p): p['wall'] for p in kept['points']}
            if fresh or kept.get('key') != self.key:
                kept = {'key': self.key, 'record': self.record, 'points': []}
            kept['claimed'] = []
            self._write(kept)
        return prior

    def claim(self, todo):
        """The first of `todo` neither done nor claimed, now claimed; None when none is."""
        with self.locked() as kept:
            taken = {ident(p) for p in kept['points'] + kept['claimed']}
            for task in todo:
                c0, v, family = task[:3]
                if (c0, round(v, 4), family) not in taken:
                    kept['claimed'].append({'c0': c0, 'v': v, 'family': family})
                    self._write(kept)
                    return task
        return None

    def add(self, p):
        with self.locked() as kept:
            kept['points'].append(p)
            kept['claimed'] = [c for c in kept['claimed'] if ident(c) != ident(p)]
            self._write(kept)

    def finish(self, elapsed):
        """Add this call's `elapsed` s to the calls' total; returns what is kept."""
        with self.locked() as kept:
            kept['elapsed'] = kept.get('elapsed', 0.0) + elapsed
            self._write(kept)
        return kept


def ident(p):
    """A point's name, (c0, v, family), from its record."""
    return p['c0'], round(p['v'], 4), p['family']


def schedule(sharps, args, prior):
    """Every point (c0, v, family, TOL, budget), the longest first (its wall in `prior`, an
    earlier points.json at any commit, else its budget), so the workers end together."""
    todo = [(sharp.c0, v, family, tol, budget) for sharp in sharps
            for v, family, tol, budget in row_points(sharp, args.tol, args.budget)]
    return sorted(todo, key=lambda t: -prior.get((t[0], round(t[1], 4), t[2]), t[4]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--tol', type=float, default=3e-3, help='TOL of the grid points')
    ap.add_argument('--budget', type=float, default=120.0, help='seconds a point')
    ap.add_argument('--max-nodes', type=int, default=25000, help='nodes a point')
    ap.add_argument('--c0', type=float, nargs='*', default=CURVATURES)
    ap.add_argument('--until', default=None, help='HH:MM UTC: no point goes past it')
    ap.add_argument('--fresh', action='store_true', help='do not go on from points.json')
    ap.add_argument('--page-only', action='store_true',
                    help='rewrite the page and the figure from points.json, no solve')
    ap.add_argument('--out', default=HERE)
    args = ap.parse_args(argv)
    args.out = os.path.abspath(args.out)
    with open(SHARP) as f:
        sharps = [Sharp(r) for r in json.load(f)['rows'] if r['c0'] in args.c0]
    path = os.path.join(args.out, 'points.json')
    if args.page_only:
        with open(path) as f:
            kept = json.load(f)
        args.workers = kept['key']['workers']
        page(args, kept['record'], sharps, kept['points'], kept.get('elapsed', math.nan))
        print(os.path.join(args.out, 'diagram.md'))
        return 0
    PETSc = pf.petsc()
    from mpi4py import MPI
    world = PETSc.COMM_WORLD.tompi4py()
    rank, args.workers = world.Get_rank(), world.Get_size()
    record = report.provenance() if rank == 0 else None
    record = world.bcast(record)
    store = Store(path, {'commit': record['commit'], 'tol': args.tol, 'budget': args.budget,
                         'max_nodes': args.max_nodes, 'workers': args.workers}, record)
    prior = world.bcast(store.start(args.fresh) if rank == 0 else None)
    todo = schedule(sharps, args, prior)
    t0 = time.perf_counter()
    while (task := store.claim(todo)) is not None:
        c0, v, family, tol, budget = task
        sharp = next(s for s in sharps if s.c0 == c0)
        p = solve_point(c0, v, family, tol, budget, args)
        p['state'], p['sharp'], p['relative'] = name_state(p, sharp)
        store.add(p)
        print(f"[{rank}] c0 {c0:g} v {v:.4f} {family}: {p['status'][:60]}, "
              f"{p.get('estimate', math.nan):.6f} +- {p.get('bar', math.nan):.2g}, "
              f"{p['state']} ({100 * p['relative']:+.3f}%), {p['wall']:.1f} s", flush=True)
    elapsed = world.allreduce(time.perf_counter() - t0, op=MPI.MAX)
    if rank == 0:
        kept = store.finish(elapsed)
        page(args, kept['record'], sharps, kept['points'], kept['elapsed'])
        print(os.path.join(args.out, 'diagram.md'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
