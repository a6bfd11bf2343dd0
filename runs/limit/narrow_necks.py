"""The level set's own energy at a narrow neck: the sharp stomatocyte at v 0.6 (R 0.4;
c0 = 2 C0 R = 0, -0.5, -1) resampled at M points of its own curve, its tangent angle from
that polyline, through `sharp.shape_energy` with the fixed 48 sine modes and with the modes
doubled until they agree (the default); written to runs/limit/narrow_necks.md.

    python runs/limit/narrow_necks.py [--out runs/limit]

Runs from any working directory, in a few seconds.
"""
import argparse
import os
import sys
import warnings

import numpy as np

from pfmembrane import report
from pfmembrane.analysis.levelset import smallest_feature, targets
from pfmembrane.sharp import solver as sharp

R, V = 0.4, 0.6


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--out', default=os.path.dirname(os.path.abspath(__file__)))
    args = ap.parse_args(argv)
    record = report.provenance()
    rows = []
    for c0 in (0.0, -0.5, -1.0):
        with warnings.catch_warnings():
            warnings.simplefilter('ignore', RuntimeWarning)
            shape = sharp.solve(V, 'stomatocyte', c0=c0 / (2 * R), radius=R)
        r, z = np.asarray(shape.r), np.asarray(shape.z)
        neck = smallest_feature((r, z))
        s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(r), np.diff(z)))])
        for m in (400, 2000):
            t = np.linspace(0.0, s[-1], m)
            rr, zz = np.interp(t, s, r), np.interp(t, s, z)
            psi = np.unwrap(np.arctan2(np.gradient(zz, t), np.gradient(rr, t)))
            psi -= psi[0]
            row = [f"{c0:g}", f"{neck.kind} {neck.size:.4f}", m, f"{shape.energy:.6f}"]
            for n in (sharp.SHAPE_MODES, None):
                e = sharp.shape_energy(np.pi * t / t[-1], psi, t[-1], *targets(R, V),
                                       c0 / (2 * R), 1.0, n=n)[0]
                row += [f"{e:.6f}", f"{100 * (e / shape.energy - 1):+.4f}%"]
            rows.append(row)
            print(' | '.join(map(str, row)), flush=True)
    lines = report.header("The level set's own energy at a narrow neck", record)
    lines += ["The sharp stomatocyte at v 0.6, R 0.4, resampled at M points of its own curve; "
              "its energy by `sharp.shape_energy` (the curve's tangent angle fitted by sine "
              "modes, put on the area and volume) with 48 modes and with the default (48 "
              "doubled until two fits agree to 1e-5, at most 512 and M / 4).", '']
    lines += report.table(['c0', 'smallest feature', 'M', 'sharp E', '48 modes', 'error',
                           'modes doubled', 'error'], rows)
    print(report.write(os.path.join(args.out, 'narrow_necks.md'), lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
