"""Narrow features under `-pf_tol 1e-3 -pf_box auto -pf_tol_time 240`: the stomatocytes at
c0 = -0.5 and -1 (v 0.6), the pear at c0 2.5 (v 0.73) and the dumbbell (prolate) at c0 2.5,
v 0.7, on NP ranks; written to runs/accuracy/narrow.md, rewritten after every run.

    python runs/accuracy/narrow.py [--np 2] [--tol 1e-3] [--budget 240] [--until HH:MM]
        [--out runs/accuracy] [--only NAME] [--page narrow.md]

--only runs the cases whose name contains NAME, --page names the page (under --out).

c0 = 2 C0 R is the reduced spontaneous curvature; `-pf_c0` takes C0 (R 0.4: C0 = c0 / 0.8).
Every run is the command line in a child process (wall time the child's, start-up included;
stdout captured for its "under-resolved" lines), its step checkpoints from an earlier run removed
first; `-pf_tol_time` is --budget cut to what is left before --until (UTC; under 30 s left:
skipped). `-pf_tol_time` is checked between steps (and a step is predicted from the last one), so
a first step can overrun it: a run still going --grace seconds past its budget is stopped
(SIGTERM to its process group, then SIGKILL) and is "not reached (killed)" with the last step
checkpoint it wrote, if any. A row per scene whatever happened: reached, not reached (with what it got), failed
(with its message). The sharp energy is the project's sharp solver's where it has the family
(stomatocyte, prolate), with its failure said where it fails; the pear's the sharp diagram's
narrow-neck pear (runs/sharp_diagram/diagram.json). Runs from any working directory.
"""
import argparse
import json
import math
import os
import sys
import warnings

import pfmembrane as pf
from pfmembrane import report, sharp
from pfmembrane.series import seconds_left
from pfmembrane.sharp.diagram import stored_energy

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)
from children import ROOT, clean, last_line, run, steps  # noqa: E402  (runs/accuracy/children.py)
R = 0.4
DISCOCYTE = ['-options_file', 'options/discocyte.opts']
DUMBBELL = ['-options_file', 'options/dumbbell.opts']
# (name, output stem, base options, branch option, v, reduced c0, sharp family)
CASES = [
    ('stomatocyte c0 -0.5', 'narrow_stomatocyte_m0.5', DISCOCYTE, 'stomatocyte', 0.6, -0.5,
     'stomatocyte'),
    ('stomatocyte c0 -1', 'narrow_stomatocyte_m1', DISCOCYTE, 'stomatocyte', 0.6, -1.0,
     'stomatocyte'),
    ('pear c0 2.5', 'narrow_pear_2.5', DISCOCYTE, 'pear', 0.73, 2.5, 'neck pear'),
    ('dumbbell (prolate) c0 2.5', 'narrow_dumbbell_2.5', DUMBBELL, 'prolate', 0.7, 2.5,
     'prolate'),
]
MIN_LEFT = 30.0


def last_step(output):
    """The last step checkpoint under `<output stem>_tol/`, or None."""
    folder = os.path.splitext(output)[0] + '_tol'
    steps = sorted((int(f[4:-3]), f) for f in os.listdir(folder)
                   if f.startswith('step') and f.endswith('.h5')) if os.path.isdir(folder) else []
    return os.path.join(folder, steps[-1][1]) if steps else None


def sharp_energy(v, family, C0):
    """(text of the sharp energy, the energy or NaN): `sharp.solve`'s, or for the
    narrow-neck branches (which need its branch following) the sharp diagram's
    (runs/sharp_diagram/diagram.json, interpolated on its grid of 0.005 in v)."""
    if family.startswith('neck'):
        with open(os.path.join(ROOT, 'runs', 'sharp_diagram', 'diagram.json')) as f:
            row = [r for r in json.load(f)['rows'] if abs(r['c0'] - 2 * C0 * R) < 1e-9][0]
        e = stored_energy(row, family, v)
        return f"{e:.6f} (the sharp diagram's {family})", e
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter('always')
            e = sharp.solve(v, family, c0=C0, radius=R).energy
        note = f" (warning: {clean(str(caught[0].message))})" if caught else ''
        return f"{e:.6f}{note}", e
    except Exception as exc:
        return f"failed: {type(exc).__name__}: {clean(str(exc))}", math.nan


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--tol', type=float, default=1e-3)
    ap.add_argument('--budget', type=float, default=240.0, help='-pf_tol_time of every run')
    ap.add_argument('--until', default=None, help='HH:MM UTC: no run goes past it')
    ap.add_argument('--grace', type=float, default=60.0,
                    help='seconds past its budget after which a run is stopped')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'accuracy'))
    ap.add_argument('--only', default=None, help='the cases whose name contains this')
    ap.add_argument('--page', default='narrow.md', help='the page written under --out')
    args = ap.parse_args(argv)
    record = report.provenance()
    out = os.path.abspath(args.out)
    rows, printed = [], []

    def write():
        lines = report.header(f"Narrow features under -pf_tol {args.tol:g}", record)
        lines += [f"{args.np} ranks, `-pf_box auto -pf_tol {args.tol:g}`, `-pf_tol_time` "
                  f"{args.budget:g} s (cut to the time left before {args.until or 'no deadline'}"
                  " UTC); every run from the scene alone. c0 = 2 C0 R (R 0.4). The estimate is "
                  "`sharp_estimate`, the bar `sharp_error`; sharp: `sharp.solve(v, family, "
                  "c0=C0, radius=0.4)` where it has the family. Topology: the final checkpoint's "
                  "phi_h = 0. Features: `tol_features` per step (NaN: not measured / unusable "
                  "step), with the last step's `tol_feature_kind`. Wall: the child process, "
                  f"start-up included; a run still going {args.grace:g} s past its budget is "
                  "stopped (killed) and reported from its last step checkpoint, if any "
                  "(`-pf_tol_time` is checked between steps).", '']
        lines += report.table(['scene', 'options', 'status', 'wall s', 'estimate', 'bar',
                               'bar / E', 'sharp', 'error vs sharp', 'topology', 'features',
                               'eps', 'nodes', 'stop'], rows)
        lines += ['', '## What the runs printed', '',
                  'The "under-resolved", "LIMIT SHAPE" and "TOL" lines of each run\'s stdout '
                  '(and a failure\'s '
                  'last stderr line).', '']
        lines += printed
        report.write(os.path.join(out, args.page), lines)

    for name, stem, base, branch, v, c0, family in CASES:
        if args.only and args.only not in name:
            continue
        C0 = c0 / (2 * R)
        scene = [*base, '-pf_branch', branch, '-pf_reduced_volume', f"{v:g}", '-pf_c0', f"{C0:g}"]
        shown = ' '.join(scene[2:])
        sharp_text, reference = sharp_energy(v, family, C0)
        output = os.path.join(out, stem + '.h5')
        budget = min(args.budget, seconds_left(args.until) - 15.0)
        if budget < MIN_LEFT:
            rows.append([name, shown, 'skipped (deadline)', '-', '-', '-', '-', sharp_text,
                         *['-'] * 6])
            printed += [f"**{name}**: skipped (deadline)", '']
            write()
            continue
        wall, code, stdout, stderr, killed = run(
            args.np, [*scene, '-pf_box', 'auto', '-pf_tol', f"{args.tol:g}",
                      '-pf_tol_time', f"{budget:.0f}"], output, budget + args.grace)
        said = [clean(t) for t in stdout.splitlines()
                if 'under-resolved' in t or 'TOL' in t or 'LIMIT SHAPE' in t]
        printed += [f"**{name}** (status {code}{', killed' if killed else ''}):", '']
        printed += [f"- `{t}`" for t in said] or ['- (no under-resolved or TOL line)']
        if killed:
            step = last_step(output)
            printed += [f"- killed after {wall:.0f} s; last step checkpoint: "
                        f"{os.path.basename(step) if step else 'none'}", '']
            if step is None:
                rows.append([name, shown, f"not reached (killed after {wall:.0f} s: no step "
                             "finished)", f"{wall:.1f}", '-', '-', '-', sharp_text, *['-'] * 6])
                print(' | '.join(map(str, rows[-1])), flush=True)
                write()
                continue
            output = step
        try:
            res = pf.read(output)
        except Exception as exc:
            message = last_line(stderr) or last_line(stdout) or str(exc)
            printed += [f"- stderr: `{message}`"]
            printed += ['']
            rows.append([name, shown, f"failed (status {code}: {message})", f"{wall:.1f}",
                         '-', '-', '-', sharp_text, *['-'] * 6])
            print(' | '.join(map(str, rows[-1])), flush=True)
            write()
            continue
        printed += ['']
        a = res.attrs
        reached = int(a['tol_reached']) if 'tol_reached' in a else 0
        estimate = float(a.get('sharp_estimate', math.nan))
        bar = float(a.get('sharp_error', math.nan))
        status = 'tol reached' if reached else 'not reached'
        if killed:
            status = f"not reached (killed after {wall:.0f} s; from {os.path.basename(output)})"
        elif code not in (0, 1):
            status = f"failed (status {code}: {last_line(stderr)}); {status}"
        features = ('-' if 'tol_features' not in a else
                    ' '.join(f"{f:.3g}" for f in a['tol_features'])
                    + (f" ({a['tol_feature_kind']})" if a.get('tol_feature_kind') else ''))
        eps, nodes = steps(a)
        rows.append([name, shown, status, f"{wall:.1f}", f"{estimate:.6f}",
                     f"{bar:.2g}" if bar == bar else '-',
                     f"{bar / abs(estimate):.2g}" if bar == bar else '-', sharp_text,
                     f"{100 * (estimate / reference - 1):+.4f}%" if reference == reference
                     else '-', res.topology or '-', features, eps, nodes,
                     clean(str(a.get('tol_stop', '-')))])
        print(' | '.join(map(str, rows[-1])), flush=True)
        write()
    print(os.path.join(out, args.page))
    return 0


if __name__ == '__main__':
    sys.exit(main())
