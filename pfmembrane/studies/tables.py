"""Regenerate the paper's uniform-grid tables (Tables 1 and 2) under runs/.

    python -m pfmembrane.studies.tables [--np 2] [--out runs/tables] [--nodes 6124,12271,24597]

Each entry is one `mpiexec -n NP python -m pfmembrane` run; its checkpoint
gives the energy, iterations, wall time and peak memory per rank.
"""
import argparse
import os

import h5py

from pfmembrane.studies import launch
from pfmembrane.scenes import FINEST, UNIFORM

SCENE = {'oblate': 'options/discocyte.opts', 'prolate': 'options/dumbbell.opts'}


def run(branch, nodes, eps, nprocs, out, extra=()):
    path = os.path.join(out, f"{branch}_n{nodes}_eps{eps:g}.h5")
    if not os.path.exists(path):
        cmd = launch.command(nprocs, '-options_file', SCENE[branch], '-pf_nodes', str(nodes),
                             '-pf_eps', str(eps), '-pf_output', path, *extra)
        print(' '.join(cmd), flush=True)
        launch.run(cmd, check=False)
    with h5py.File(path, 'r') as f:
        return dict(f.attrs)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--out', default='runs/tables')
    ap.add_argument('--nodes', default='6124,12271,24597')
    ap.add_argument('--branches', default='oblate,prolate')
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    rows = ['| branch | nodes | eps | E (pfmembrane) | E paper (same grid) | diff | E paper (296,344) '
            '| diff | nu_A | nu_V | max phi | its (1+2) | converged | wall s | peak MB/rank |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for branch in args.branches.split(','):
        for n in (int(v) for v in args.nodes.split(',')):
            for eps, ref in UNIFORM[(branch, n)].items():
                a = run(branch, n, eps, args.np, args.out)
                fine = UNIFORM[(branch, FINEST)][eps]
                rows.append(
                    f"| {branch} | {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | {ref:.5f} | "
                    f"{100 * (a['energy'] / ref - 1):+.2f}% | {fine:.5f} | {100 * (a['energy'] / fine - 1):+.2f}% | "
                    f"{a['nu_area']:.4f} | {a['nu_volume']:.3f} | {a.get('max_phi', float('nan')):.4f} | "
                    f"{int(a['stage1_iterations'])}+{int(a['stage2_iterations'])} | {int(a['converged'])} | "
                    f"{a['wall_time']:.1f} | {a['peak_rss_mb']:.0f} |")
                print(rows[-1], flush=True)
    table = os.path.join(args.out, 'uniform.md')
    with open(table, 'w') as f:
        f.write(f"Uniform grids, {args.np} MPI ranks, gamma 0.8, cut-off 1e-6, degree-4 rule "
                "(6 points per triangle), axis mirrors. Regenerate: `make tables`.\n\n")
        f.write('\n'.join(rows) + '\n')
    print(table)


if __name__ == '__main__':
    main()
