"""compare.py REFERENCE ATLAS...: each atlas' stomatocyte branch at c0 0 against the
REFERENCE atlas' (the uniform grid's), at the reference's v: E, the level set, nu_A and
nu_V of the other branch interpolated linearly along its stable stretch (index 0)
between its folds, and the folds (index changes) of each."""
import json
import sys

import numpy as np


def branch(path):
    b = next(b for b in json.load(open(path))['branches']
             if b['family'] == 'stomatocyte' and b['c0'] == 0.0)
    pts = sorted((p for p in b['points'] if p['converged']),
                 key=lambda p: p['direction'] * p['arclength'])  # down before up
    folds = [0.5 * (p['v'] + q['v']) for p, q in zip(pts, pts[1:]) if p['index'] != q['index']]
    return pts, folds, b['nodes']


ref, ref_folds, n_ref = branch(sys.argv[1])
stable = sorted((p for p in ref if p['index'] == 0), key=lambda p: p['v'])
print(f"{sys.argv[1]}: {n_ref} nodes, {len(ref)} points, index changes near v "
      + ', '.join(f'{v:.4f}' for v in ref_folds))
for path in sys.argv[2:]:
    pts, folds, n = branch(path)
    print(f"\n{path}: {n} nodes, {len(pts)} points, index changes near v "
          + ', '.join(f'{v:.4f}' for v in folds))
    # the other branch's stable stretch, one value per v, between its index changes
    mine = sorted((p for p in pts if p['index'] == 0), key=lambda p: p['v'])
    v = np.array([p['v'] for p in mine])
    if not np.all(np.diff(v) > 0):
        sys.exit(f"{path}: the points of index 0 are not one stretch in v")
    print("| v | dE | d level | d nu_A | d nu_V |\n|---|---|---|---|---|")
    for p in stable:
        if not v[0] <= p['v'] <= v[-1]:
            continue
        d = [np.interp(p['v'], v, [q[k] for q in mine]) - p[k]
             for k in ('E', 'level', 'nu_A', 'nu_V')]
        print(f"| {p['v']:.4f} | {d[0]:+.2e} | {d[1]:+.2e} | {d[2]:+.4f} | {d[3]:+.3f} |")
