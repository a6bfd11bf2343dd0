"""Table 4 of the paper, regenerated from adaptive sequences: the discocyte's
relative energy error (%) against the sharp interface, per grid and eps.

    python runs/adapt/table4.py options/adapt/discocyte options/adapt/discocyte_12271 \\
        options/adapt/discocyte_24597 --out runs/adapt/table4.md

Each sequence directory gives one row. Its cell at an eps is the converged
step of least energy at that eps: a Ritz-Galerkin minimum bounds the phase
field's minimum from above (quadrature and support cut-off aside), so of two
grids the lower energy is the better resolved. Each cell shows ours, the
paper's and the difference in percentage points.

Runs from any working directory: the directories are found there or else in
the repository, whose root is where their steps' checkpoints are and where
the default page runs/adapt/table4.md goes.
"""
import argparse
import contextlib
import os
import sys

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.cli.runner import converged, output_of, steps_of
from pfmembrane.paper import FINEST, SHARP, SHARP_ERROR, grid_name, paper_grid

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
COLUMNS = (0.03, 0.025, 0.02, 0.015, 0.01, 0.007, 0.005)


def found(path):
    """`path` from the working directory if it is there, else from the repository."""
    return os.path.abspath(path if os.path.exists(path) else os.path.join(ROOT, path))


def shown(path):
    """`path` relative to the repository when it is inside it, for the page."""
    rel = os.path.relpath(path, ROOT)
    return path if rel.startswith(os.pardir) else rel


def cells(directory):
    """(nominal node count, half box?, {eps: (error %, grid, gamma)}) of the
    sequence's converged checkpoints, the least energy of each eps winning."""
    found, nominal, half = {}, None, False
    for step in steps_of(directory):
        path = output_of(step)
        if not converged(path):
            continue
        a = pf.read(path).attrs
        if str(a['branch']) != 'oblate':
            sys.exit(f"{path}: Table 4 is of the discocyte (oblate), not {a['branch']}")
        half, nominal, grid = bool(a.get('symmetric', 0)), paper_grid(a), grid_name(path)
        eps = round(float(a['eps']), 6)
        error = 100 * (float(a['energy']) / SHARP['oblate'] - 1)
        if eps not in found or error < found[eps][0]:
            found[eps] = (error, grid, float(a['gamma']))
    return nominal, half, found


def table(directories):
    """Markdown rows: one per sequence, then the paper's finest uniform grid;
    and the count of cells within 0.1 points of the paper's, of those compared."""
    head = '| nodes | box | ' + ' | '.join(f'eps {e:g}' for e in COLUMNS) + ' | max abs diff |'
    rows = [head, '|' + '---|' * (len(COLUMNS) + 3)]
    within = compared = 0
    for directory in directories:
        nominal, half, found = cells(directory)
        if nominal is None:
            continue
        paper = SHARP_ERROR.get(nominal, {})
        line, worst = [], 0.0
        for eps in COLUMNS:
            ours, ref = found.get(eps), paper.get(eps)
            if ours is None:
                line.append('' if ref is None else f'({ref:.2f})')
                continue
            error, grid, gamma = ours
            cell = f'{error:.2f} {grid}' + ('' if gamma == 0.5 else f' g{gamma:g}')
            if ref is not None:
                diff = error - ref
                worst = max(worst, abs(diff))
                compared += 1
                within += abs(diff) <= 0.1 + 5e-9
                cell += f' ({ref:.2f}, {diff:+.2f})'
            line.append(cell)
        rows.append(f"| {nominal} | {'half' if half else 'full'} | " + ' | '.join(line)
                    + f' | {worst:.2f} |')
    finest = SHARP_ERROR[FINEST]
    rows.append(f'| {FINEST} uniform (paper) | full | '
                + ' | '.join('' if e not in finest else f'{finest[e]:.2f}' for e in COLUMNS) + ' | |')
    return rows, within, compared


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('directories', nargs='+', help='discocyte sequence directories of step options')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'adapt', 'table4.md'))
    args = ap.parse_args(argv)
    record = report.provenance()
    directories, out = [found(d) for d in args.directories], os.path.abspath(args.out)
    # The steps name their checkpoints relative to the repository.
    with contextlib.chdir(ROOT):
        rows, within, compared = table(directories)
    with open(out, 'w') as f:
        f.write('\n'.join(report.header('Table 4', record)) + '\n')
        f.write('Table 4: relative energy error (%) of the adapted discocytes against the sharp '
                f"interface {SHARP['oblate']}; each cell is ours on the named grid (gamma 0.5 "
                "unless g is given), then (the paper's, ours minus the paper's in points); "
                "a bracket alone is a paper entry with no converged run here. Regenerate: "
                f"`python runs/adapt/table4.py {' '.join(map(shown, directories))} "
                f"--out {shown(out)}`.\n\n")
        f.write('\n'.join(rows) + '\n\n')
        f.write(f'{within} of {compared} cells within 0.1 points of the paper.\n')
    print('\n'.join(rows))
    print(f'{within} of {compared} cells within 0.1 points of the paper -> {args.out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
