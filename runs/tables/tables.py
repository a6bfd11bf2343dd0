"""Regenerate the paper's uniform-grid tables (Tables 1 and 2) under runs/tables/.

    python runs/tables/tables.py [--np 2] [--out runs/tables] [--nodes 6124,12271,24597]

Each entry is the run `python -m pfmembrane -options_file SCENE -pf_nodes N
-pf_eps EPS` would make, all in one process on NP ranks (started under
mpiexec if need be), every eps of a grid on that grid built once; its
checkpoint gives the energy, iterations, wall time (set-up on the first eps of
a grid) and the process's peak memory per rank so far. Existing checkpoints
are reused. Runs from any working directory: the scenes are the repository's
options files, and --out defaults to its runs/tables.
"""
import argparse
import os
import sys

from pfmembrane import report, series
from pfmembrane.cli import runner
from pfmembrane.paper import FINEST, SCENE_FILES, UNIFORM

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(branch, nodes, eps, out, cache):
    """The checkpoint attributes of one entry, solved unless its checkpoint exists."""
    path = os.path.join(out, f"{branch}_n{nodes}_eps{eps:g}.h5")
    return runner.solved(os.path.join(ROOT, SCENE_FILES[branch]),
                         ['-pf_nodes', str(nodes), '-pf_eps', str(eps)], path, cache).attrs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'tables'))
    ap.add_argument('--nodes', default='6124,12271,24597')
    ap.add_argument('--branches', default='oblate,prolate')
    args = ap.parse_args(argv)
    series.ensure_ranks(args.np, __file__, sys.argv[1:])
    record = report.provenance()
    from mpi4py import MPI
    cache, root = runner.Cache(), MPI.COMM_WORLD.Get_rank() == 0
    os.makedirs(args.out, exist_ok=True)
    rows = ['| branch | nodes | eps | E (pfmembrane) | E paper (same grid) | diff | E paper (296,344) '
            '| diff | nu_A | nu_V | max phi | its (1+2) | converged | wall s | peak MB/rank |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for branch in args.branches.split(','):
        for n in (int(v) for v in args.nodes.split(',')):
            for eps, ref in UNIFORM[(branch, n)].items():
                a = run(branch, n, eps, args.out, cache)
                fine = UNIFORM[(branch, FINEST)][eps]
                rows.append(
                    f"| {branch} | {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | {ref:.5f} | "
                    f"{100 * (a['energy'] / ref - 1):+.2f}% | {fine:.5f} | {100 * (a['energy'] / fine - 1):+.2f}% | "
                    f"{a['nu_area']:.4f} | {a['nu_volume']:.3f} | {a.get('max_phi', float('nan')):.4f} | "
                    f"{report.iterations(a['stage1_iterations'])}+{report.iterations(a['stage2_iterations'])} | "
                    f"{int(a['converged'])} | {a['wall_time']:.1f} | {a['peak_rss_mb']:.0f} |")
                if root:
                    print(rows[-1], flush=True)
    if not root:
        return 0
    table = os.path.join(args.out, 'uniform.md')
    with open(table, 'w') as f:
        f.write('\n'.join(report.header('Uniform grids (Tables 1 and 2)', record)) + '\n')
        f.write(f"Uniform grids, {MPI.COMM_WORLD.Get_size()} MPI ranks, gamma 0.8, cut-off 1e-6, "
                "degree-4 rule (6 points per triangle), axis mirrors; the eps of a grid solved on "
                "it in one process. Regenerate: `make tables`.\n\n")
        f.write('\n'.join(rows) + '\n')
    print(table)
    return 0


if __name__ == '__main__':
    sys.exit(main())
