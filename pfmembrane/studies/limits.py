"""Two exact limits as eps falls (runs/limits/notes.md):

    python -m pfmembrane.studies.limits [--np 2] [--out runs/limits] [--only clifford]

the Clifford torus (options/limits/clifford.opts: E -> pi^2 k, both multipliers -> 0,
radii in ratio 1 : sqrt 2) and symmetric budding (options/limits/budding.opts: two spheres
of radius R / sqrt 2 with H = C0, E -> 0). Each row is the run `python -m pfmembrane
-options_file SCENE -pf_nodes N -pf_eps EPS` would make, from the scene's own start, all in
one process on NP ranks (started under mpiexec if need be), the rows of one grid on that grid
built once. Existing checkpoints are reused. The level set of phi_h is measured by
`analysis.limit`: its topology, the torus's own energy (`loop_energy`) and radii, the
spheres' radii (half their heights, and their widths).
"""
import argparse
import math
import os
import sys

import numpy as np

from pfmembrane.studies import launch

# (eps, nodes) of each limit, the grid resolving the smallest eps on its box.
ROWS = {'clifford': [(0.04, 6124), (0.03, 6124), (0.02, 6124), (0.015, 10000)],
        'budding': [(0.04, 3000), (0.03, 5000)]}
SCENES = {name: os.path.join('options', 'limits', f'{name}.opts') for name in ROWS}


def run(name, eps, nodes, out, cache):
    """The checkpoint of one row, solved unless it exists."""
    from pfmembrane import run as runs
    path = os.path.join(out, f"{name}_n{nodes}_eps{eps:g}.h5")
    return runs.solved(SCENES[name], ['-pf_nodes', str(nodes), '-pf_eps', str(eps)], path,
                       cache).checkpoint()


def measure(ckpt):
    """Topology of phi_h = 0, and per piece: a torus's energy and (tube, centre-line)
    radii; a sphere's half height and largest r."""
    from pfmembrane.analysis import limit
    field = limit.PhaseField(ckpt)
    curve = limit.level_set(ckpt, field=field)
    shape = limit.topology(curve, ckpt.box)
    tori = [limit.loop_energy(ckpt, piece, field) for piece in curve
            if piece[:, 0].min() > 1e-3 * max(ckpt.box)]
    spheres = sorted((0.5 * float(np.ptp(piece[:, 1])), float(piece[:, 0].max()))
                     for piece in curve if piece[:, 0].min() <= 1e-3 * max(ckpt.box))
    return shape['label'], tori, spheres


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--out', default='runs/limits')
    ap.add_argument('--only', choices=sorted(ROWS), help='one limit only')
    args = ap.parse_args(argv)
    launch.ensure_ranks(args.np, 'pfmembrane.studies.limits', sys.argv[1:])
    from pfmembrane import run as runs
    from mpi4py import MPI
    cache, root = runs.Cache(), MPI.COMM_WORLD.Get_rank() == 0
    os.makedirs(args.out, exist_ok=True)
    lines = [f"{MPI.COMM_WORLD.Get_size()} MPI ranks, {os.cpu_count()} cores. Regenerate: "
             "`make limits` (`python -m pfmembrane.studies.limits`).", '']
    for name in [args.only] if args.only else ROWS:
        rows = []
        for eps, nodes in ROWS[name]:
            ck = run(name, eps, nodes, args.out, cache)
            a = ck.attrs
            label, tori, spheres = measure(ck) if root else ('', [], [])
            rows.append((eps, nodes, a, label, tori, spheres))
        if name == 'clifford':
            lines += ['## The Clifford torus: E -> pi^2 = 9.869604, nu -> 0, b / a -> sqrt 2', '',
                      '| nodes | eps | E | E / pi^2 - 1 | nu_A | nu_V | phi_h = 0 | its (1+2) | converged '
                      '| wall s | level-set E | vs pi^2 | tube a | centre b | b / a |',
                      '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
            for eps, nodes, a, label, tori, _ in rows:
                e, (tube, centre) = tori[0] if len(tori) == 1 else (math.nan, (math.nan,) * 2)
                lines.append(
                    f"| {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | "
                    f"{100 * (a['energy'] / math.pi ** 2 - 1):+.2f}% | {a['nu_area']:.4f} | "
                    f"{a['nu_volume']:.3f} | {label} | {int(a['stage1_iterations'])}+"
                    f"{int(a['stage2_iterations'])} | {int(a['converged'])} | {a['wall_time']:.1f} | {e:.5f} | "
                    f"{100 * (e / math.pi ** 2 - 1):+.3f}% | {tube:.4f} | {centre:.4f} | "
                    f"{centre / tube:.4f} |")
        else:
            target = 0.4 / math.sqrt(2)
            lines += [f'## Symmetric budding: two spheres of radius R / sqrt 2 = {target:.5f}, E -> 0',
                      '', '| nodes | eps | E | nu_A | nu_V | phi_h = 0 | its (1+2) | converged | wall s '
                      '| half heights | vs R/sqrt2 | largest r | vs R/sqrt2 |',
                      '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
            for eps, nodes, a, label, _, spheres in rows:
                halves = ', '.join(f"{h:.5f}" for h, _ in spheres)
                widths = ', '.join(f"{w:.5f}" for _, w in spheres)
                lines.append(
                    f"| {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | {a['nu_area']:.4f} | "
                    f"{a['nu_volume']:.3f} | {label} | {int(a['stage1_iterations'])}+"
                    f"{int(a['stage2_iterations'])} | {int(a['converged'])} | {a['wall_time']:.1f} | {halves} | "
                    + ', '.join(f"{100 * (h / target - 1):+.2f}%" for h, _ in spheres)
                    + f" | {widths} | "
                    + ', '.join(f"{100 * (w / target - 1):+.2f}%" for _, w in spheres) + " |")
        lines.append('')
    if root:
        table = os.path.join(args.out, f"limits{'_' + args.only if args.only else ''}.md")
        with open(table, 'w') as f:
            f.write('\n'.join(lines))
        print('\n'.join(lines))
        print(table)


if __name__ == '__main__':
    main()
