"""Time to accuracy: the wall time of `-pf_tol TOL` (with `-pf_box auto`) for TOL = 1e-2, 3e-3,
1e-3, 3e-4 (and 1e-4) on the discocyte, the dumbbell and the stomatocyte at v 0.6, each TOL a
run of its own from the scene files alone (no step checkpoints kept), on NP ranks; written to
runs/accuracy/curve.md (--page), rewritten after every run.

    python runs/accuracy/curve.py [--np 2] [--tols 1e-2,3e-3,1e-3,3e-4,1e-4]
        [--budget 150] [--until HH:MM] [--out runs/accuracy] [--page curve.md] [--no-hand]

The TOLs go cheap first, every scene at one TOL before the next TOL. Every run is the command
line in a child process (its wall time the child's, start-up included) with `-pf_tol_time`
= --budget seconds, cut to what is left before --until (UTC; a run with under 30 s left is
skipped and its row says so). A run that stops at its budget is "not reached" with what it got;
one that fails keeps its row with its message. The true error is against the project's sharp
solver (R 0.4). Runs from any working directory.

Beside each run, the best hand-written sequence for the same accuracy: the two solves that made
its error bar (its last two estimates: the same eps, the same uniform node counts on the same
`-pf_box auto`), written as two command lines `-pf_eps E -pf_nodes N`, each from the scene's
start, as a user who knew them would; its wall the two children's, its bar the driver's rule
on their level-set energies. --no-hand skips them.
"""
import argparse
import os
import sys

import pfmembrane as pf
from pfmembrane import report, sharp
from pfmembrane.series import seconds_left

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)
from children import ROOT, last_line, run, steps  # noqa: E402  (runs/accuracy/children.py)
from pfmembrane.accuracy import error_bar, Step  # noqa: E402
# (name, options of the scene, family, v)
CASES = [
    ('discocyte', ['-options_file', 'options/discocyte.opts'], 'oblate', 0.8),
    ('dumbbell', ['-options_file', 'options/dumbbell.opts'], 'prolate', 0.8),
    ('stomatocyte v 0.6', ['-options_file', 'options/discocyte.opts', '-pf_branch', 'stomatocyte',
                           '-pf_reduced_volume', '0.6'], 'stomatocyte', 0.6),
]
MIN_LEFT = 30.0  # seconds: a run with less left before --until is skipped


def by_hand(np_, scene, attrs, out, name, tol, wall):
    """The table cells of the hand-written sequence of a run with `attrs` (its last two
    estimates' eps and nodes, each a command line from the scene's start)."""
    usable = [(e, int(n)) for e, n, x in zip(attrs['tol_eps'], attrs['tol_nodes'],
                                            attrs['tol_estimates']) if x == x][-2:]
    if len(usable) < 2:
        return ['no two estimates', '-', '-', '-']
    walls, hand = [], []
    for e, n in usable:
        output = os.path.join(out, f"hand_{name.split()[0]}_{tol:g}_{e:.4g}.h5")
        w, code, stdout, stderr, _ = run(np_, [*scene, '-pf_box', 'auto', '-pf_eps', f"{e!r}",
                                               '-pf_nodes', str(n)], output)
        walls.append(w)
        try:
            hand.append(Step(e, n, e, pf.read(output).level_set_energy, True, True, w, 0.0, ''))
        except Exception:
            return [f"failed at eps {e:.3g}: {last_line(stderr) or last_line(stdout)}",
                    f"{sum(walls):.1f}", '-', '-']
    value, bar = error_bar(hand)
    return [' '.join(f"{e:.3g} ({n})" for e, n in usable), f"{sum(walls):.1f}",
            f"{value:.6f} +- {bar:.2g}", f"{wall / sum(walls):.2f}"]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--tols', default='1e-2,3e-3,1e-3,3e-4,1e-4')
    ap.add_argument('--budget', type=float, default=150.0, help='-pf_tol_time of every run')
    ap.add_argument('--until', default=None, help='HH:MM UTC: no run goes past it')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'accuracy'))
    ap.add_argument('--no-hand', action='store_true', help='no hand-written sequences')
    ap.add_argument('--page', default='curve.md', help='the page written under --out')
    args = ap.parse_args(argv)
    record = report.provenance()
    out = os.path.abspath(args.out)
    tols = [float(t) for t in args.tols.split(',')]
    references = {(family, v): sharp.energy_reference(v, family, radius=0.4)
                  for _, _, family, v in CASES}
    rows = []

    def write():
        lines = report.header('Time to accuracy: wall time of -pf_tol TOL', record)
        lines += [f"{args.np} ranks, `-pf_box auto`, `-pf_tol_time` {args.budget:g} s (cut to "
                  f"the time left before {args.until or 'no deadline'} UTC); every run from the "
                  "scene alone (earlier step checkpoints removed). The estimate is "
                  "`sharp_estimate` (the level set's own energy), the bar `sharp_error`, the "
                  "sharp energy the project's sharp solver's (R 0.4). Wall: the child process, "
                  "start-up included. Status: reached (tol_reached 1), not reached (stopped at "
                  "the budget with the best estimate), failed, skipped (deadline).", '']
        lines += report.table(['scene', 'TOL', 'status', 'wall s', 'budget s', 'estimate',
                               'bar', 'bar / E', 'sharp', 'true error', 'bar / true error',
                               'tol reached', 'eps', 'nodes', 'stop', 'hand: eps (nodes)',
                               'hand wall s', 'hand estimate +- bar', 'wall / hand wall'], rows)
        report.write(os.path.join(out, args.page), lines)

    for tol in tols:
        for name, scene, family, v in CASES:
            reference = references[family, v]
            output = os.path.join(out, f"curve_{name.split()[0]}_{tol:g}.h5")
            budget = min(args.budget, seconds_left(args.until) - 15.0)
            if budget < MIN_LEFT:
                rows.append([name, f"{tol:g}", 'skipped (deadline)', '-', f"{budget:.0f}",
                             *['-'] * 10])
                print(' | '.join(map(str, rows[-1])), flush=True)
                write()
                continue
            wall, code, stdout, stderr, _ = run(
                args.np, [*scene, '-pf_box', 'auto', '-pf_tol', f"{tol:g}",
                          '-pf_tol_time', f"{budget:.0f}"], output)
            try:
                res = pf.read(output)
            except Exception as exc:  # no checkpoint: the run failed
                rows.append([name, f"{tol:g}", f"failed (status {code}: "
                             f"{last_line(stderr) or last_line(stdout) or exc})", f"{wall:.1f}",
                             f"{budget:.0f}", *['-'] * 10])
                print(' | '.join(map(str, rows[-1])), flush=True)
                write()
                continue
            a = res.attrs
            reached = int(a['tol_reached']) if 'tol_reached' in a else 0
            estimate = float(a.get('sharp_estimate', float('nan')))
            bar = float(a.get('sharp_error', float('nan')))
            status = 'reached' if reached else 'not reached'
            if code not in (0, 1):
                status += f" (status {code}: {last_line(stderr)})"
            eps, nodes = steps(a)
            error = estimate / reference - 1
            hand = ['-'] * 4 if args.no_hand else by_hand(args.np, scene, a, out, name, tol, wall)
            rows.append([name, f"{tol:g}", status, f"{wall:.1f}", f"{budget:.0f}",
                         f"{estimate:.6f}", f"{bar:.2g}" if bar == bar else '-',
                         f"{bar / abs(estimate):.2g}" if bar == bar else '-',
                         f"{reference:.6f}", f"{100 * error:+.4f}%",
                         f"{bar / abs(estimate - reference):.1f}"
                         if bar == bar and estimate != reference else '-',
                         reached, eps, nodes, str(a.get('tol_stop', '-')).replace('|', '/'),
                         *hand])
            print(' | '.join(map(str, rows[-1])), flush=True)
            write()
    print(os.path.join(out, args.page))
    return 0


if __name__ == '__main__':
    sys.exit(main())
