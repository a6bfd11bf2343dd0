"""Accuracy on demand against hand-picked runs: `-pf_tol TOL` from the scene files alone
(the discocyte, the dumbbell, the stomatocyte at v 0.6), each beside one run with settings
picked by hand, on NP ranks; written to runs/accuracy/tol.md.

    python runs/accuracy/accuracy.py [--np 2] [--tol 1e-3] [--out runs/accuracy]

Every run is the command line in a child process (its wall time is the child's, start-up
included; `children.run`), its checkpoint written under --out; the sharp-interface energy is the project's sharp
solver's. Runs from any working directory.
"""
import argparse
import os
import sys

import pfmembrane as pf
from pfmembrane import report, sharp

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:
    sys.path.insert(0, HERE)
from children import ROOT, run  # noqa: E402  (runs/accuracy/children.py)
# (name, options of the scene, the hand-picked run's options, family, v)
CASES = [
    ('discocyte', ['-options_file', 'options/discocyte.opts'], [], 'oblate', 0.8),
    ('dumbbell', ['-options_file', 'options/dumbbell.opts'], [], 'prolate', 0.8),
    ('stomatocyte v 0.6', ['-options_file', 'options/discocyte.opts', '-pf_branch', 'stomatocyte',
                           '-pf_reduced_volume', '0.6'],
     ['-pf_eps', '0.01', '-pf_box', '0.42,0.78', '-pf_nodes', '9171'], 'stomatocyte', 0.6),
]


def solve(np_, args, output):
    """Wall seconds and the result of the command line with `args` (`children.run`)."""
    wall, code, _, stderr, _ = run(np_, args, output)
    if code not in (0, 1):
        sys.exit(f"{' '.join(args)}: status {code}\n{stderr}")
    return wall, pf.read(output)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--tol', type=float, default=1e-3)
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'accuracy'))
    args = ap.parse_args(argv)
    record = report.provenance()
    out = os.path.abspath(args.out)
    rows = []
    for name, scene, hand, family, v in CASES:
        reference = sharp.energy_reference(v, family, radius=0.4)
        stem = os.path.join(out, name.split()[0])
        for mode, extra, suffix in (('-pf_tol', ['-pf_box', 'auto', '-pf_tol', str(args.tol)],
                                     'tol'), ('by hand', hand, 'hand')):
            wall, res = solve(args.np, [*scene, *extra], f"{stem}_{suffix}.h5")
            a = res.attrs
            estimate = float(a.get('sharp_estimate', a.get('level_set_energy', float('nan'))))
            bar = float(a['sharp_error']) if 'sharp_error' in a else float('nan')
            eps = ' '.join(f"{e:g}" for e in a['tol_eps']) if 'tol_eps' in a else f"{res.eps:g}"
            nodes = (' '.join(str(int(n)) for n in a['tol_nodes']) if 'tol_nodes' in a
                     else str(int(a['n_nodes'])))
            error = estimate / reference - 1
            rows.append([name, mode, f"{wall:.1f}", f"{estimate:.6f}",
                         f"{bar:.2g}" if bar == bar else '-', f"{reference:.6f}",
                         f"{100 * error:+.4f}%", f"{bar / abs(estimate - reference):.1f}"
                         if bar == bar and estimate != reference else '-',
                         int(a.get('tol_reached', 0)) if 'tol_reached' in a else '-',
                         eps, nodes])
            print(' | '.join(map(str, rows[-1])), flush=True)
    lines = report.header(f"Accuracy on demand: -pf_tol {args.tol:g} against hand-picked runs",
                          record)
    lines += [f"{args.np} ranks; the estimate is the level set's own energy (`sharp_estimate` "
              "for -pf_tol, `level_set_energy` by hand), the sharp energy the project's sharp "
              "solver's (R 0.4). Wall: the child process, start-up included.", '']
    lines += report.table(['scene', 'run', 'wall s', 'estimate', 'bar', 'sharp',
                           'true error', 'bar / true error', 'tol reached', 'eps', 'nodes'], rows)
    print(report.write(os.path.join(out, 'tol.md'), lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
