"""Cost of the harmonics: the paper's discocyte (v 0.8, eps 0.04, 6,124 nodes) solved
axisymmetric and with the five cosine harmonics m = 0, 2, 4, 6, 8 (-pf_harmonics 4
-pf_dihedral 2), each from its fresh start (the spheroid; with harmonics, the deterministic
-pf_perturb in every m > 0), in turn, REPEAT times, in one sitting: wall time (the solve and
its checks apart), peak memory, Newton and Krylov iterations. Under mpiexec; written to
runs/harmonics/cost.md.

    mpiexec -n 2 python runs/harmonics/cost.py [--repeat 2] [--harmonics 4]
"""
import argparse
import dataclasses
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report

HERE = os.path.dirname(os.path.abspath(__file__))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeat', type=int, default=2)
    ap.add_argument('--harmonics', type=int, default=4)
    ap.add_argument('--out', default=os.path.join(HERE, 'cost.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    record = report.provenance()
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid = pf.Grid.uniform(scene, nodes=6124)
    scenes = {'axisymmetric': scene,
              f'm = 0..{2 * args.harmonics} (cosines)':
                  dataclasses.replace(scene, harmonics=args.harmonics, dihedral=2)}
    times = {name: [] for name in scenes}
    last = {}
    for _ in range(args.repeat):
        for name, s in scenes.items():
            t = time.perf_counter()
            r = pf.solve(s, grid, 0.04)
            times[name].append(time.perf_counter() - t)
            last[name] = r
    if PETSc.COMM_WORLD.getRank() == 0:
        write(args, record, times, last)


def write(args, record, times, last):
    base = np.median(times['axisymmetric'])
    rows = []
    for name, t in times.items():
        a = last[name].attrs
        newton = a['stage2_iterations']
        krylov = a['stage2_linear_iterations']
        rows.append([name, last[name].converged, f"{a['energy']:.8f}",
                     ', '.join(f"{x:.1f}" for x in t), f"{np.median(t) / base:.2f}",
                     f"{a['time_stage1']:.1f} / {a['time_stage2']:.1f}",
                     f"{a['stage1_iterations']} / {newton}",
                     f"{krylov / max(newton, 1):.1f}" if name != 'axisymmetric' else '1 (direct)',
                     f"{a['peak_rss_mb']:.0f}"])
    lines = report.header('Cost of the harmonics on the paper\'s discocyte', record)
    lines += ["v 0.8, c0 0, eps 0.04, 6,124 uniform nodes (the paper's), 2 ranks, each solve from "
              "its fresh start; the runs alternate, "
              f"{args.repeat} of each. Wall: `pf.solve` without the phase-field checks. "
              "Krylov per Newton step: stage 2's GMRES iterations over its Newton steps (the "
              "axisymmetric stage 2 factors its exact Jacobian). Peak memory: the largest "
              "resident set of the ranks.", '']
    lines += report.table(['solve', 'converged', 'E', 'wall s (each run)', 'wall / axisymmetric',
                           'stage 1 / 2 s', 'Newton its (stage 1 / 2)',
                           'Krylov its per Newton step', 'peak MB'], rows)
    report.write(args.out, lines)
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
