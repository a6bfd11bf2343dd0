"""The three-fold shapes out of the oblate at SBL's reduced spontaneous curvature c0 = 2 C0 R
= 2.8 (pde2path's vesicle demo: C0 R = 1.4): at each v of a sequence (down past the oblate's
m = 3 bifurcation, back up beyond it, which a three-fold branch reaches only if the
bifurcation is subcritical, then down again) the axisymmetric oblate (from the last v's)
and its m = 3 eigenvalue, and the solve with the
harmonics m = 0, 3, ..., 3J (-pf_dihedral 3): a fresh one (the oblate solved, then pushed
along its m = 3 critical mode where that is unstable) until a three-fold state exists, then
from the last v's three-fold state: natural continuation in v, not arclength. eps 0.04 on
the paper's spacing (6,124 nodes of the full box), half box. Under mpiexec; the table is
rewritten after every v to runs/harmonics/threefold.md.

    mpiexec -n 2 python runs/harmonics/threefold.py [--v 0.96,0.95,0.953,0.956,0.94,...]
        [--harmonics 2] [--until HH:MM]
"""
import argparse
import dataclasses
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.series import seconds_left

HERE = os.path.dirname(os.path.abspath(__file__))
C0, EPS, RADIUS = 2.8, 0.04, 0.4   # C0: the reduced 2 C0 R


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--v', default='0.96,0.95,0.953,0.956,0.94,0.93,0.92,0.9')
    ap.add_argument('--harmonics', type=int, default=2)
    ap.add_argument('--until', default=None)
    ap.add_argument('--out', default=os.path.join(HERE, 'threefold.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    mpi = PETSc.COMM_WORLD.tompi4py()
    record = report.provenance()
    rows = []
    oblate = threefold = None
    grid = None
    for v in map(float, args.v.split(',')):
        if mpi.bcast(seconds_left(args.until), root=0) < 120:
            rows.append([v] + ['skipped (deadline)'] + [''] * 10)
            continue
        scene = pf.Scene(reduced_volume=v, c0=C0 / (2 * RADIUS), radius=RADIUS, branch='oblate',
                         symmetric=True)
        grid = grid or pf.Grid.uniform(scene, nodes=6124)
        oblate = pf.solve(scene, grid, EPS, start=oblate)
        lowest = pf.stability(oblate, modes=3, nev=2)[3].eigenvalues[0]
        harmonic = dataclasses.replace(scene, harmonics=args.harmonics, dihedral=3)
        t = time.perf_counter()
        r = pf.solve(harmonic, grid, EPS, start=threefold, checks=True)
        seconds = time.perf_counter() - t
        index = pf.stability(r) if r.converged else None
        amplitude = np.abs(grid.nodes[:, 0] ** 3 * r.phi[:, 1]).max()
        pushed = ('m = ' + ', '.join(map(str, r.attrs['start_unstable_m']))
                  if len(r.attrs.get('start_unstable_m', [])) else
                  'none' if threefold is None else 'continued')
        if r.converged and amplitude > 1e-6:
            threefold = r
        rows.append([v, f"{oblate.energy:.6f}", f"{lowest:.4g}", pushed,
                     f"{r.energy:.6f}" if r.converged else f"not converged ({r.message})",
                     f"{r.energy - oblate.energy:.3e}", f"{amplitude:.4f}",
                     f"{r.attrs.get('level_set_energy', np.nan):.5f}",
                     r.attrs.get('topology', '-'), '-' if index is None else index,
                     f"{r.attrs['stage1_iterations']} / {r.attrs['stage2_iterations']}",
                     f"{seconds:.0f}"])
        if mpi.Get_rank() == 0:
            write(args, record, rows)
    if mpi.Get_rank() == 0:
        write(args, record, rows)


def write(args, record, rows):
    lines = report.header('Three-fold shapes out of the oblate at c0 2.8', record)
    lines += [f"Reduced c0 = 2 C0 R = {C0} (C0 R 1.4; C0 {C0 / (2 * RADIUS):g} at R {RADIUS}), "
              f"eps {EPS}, 6,124 nodes of the full box (half box z >= Zb/2), 2 ranks; "
              f"harmonics m = 0, 3, ..., {3 * args.harmonics} (cosines). The oblate at each v "
              "from the last v's. The three-fold solve: fresh (the oblate solved, pushed along "
              "the critical mode of each harmonic unstable there: 'pushed') until a three-fold "
              "state exists, then from the last v's ('continued'). lambda_3: the oblate's lowest "
              "m = 3 eigenvalue (negative: unstable). max |psi_3|: the largest r^3 |chi_3| at a "
              "node. index: the three-fold state's negative eigenvalues within m = 0, 3, ... "
              "on the constraints' tangent space (`pf.stability`: the inertia of the exact "
              "coupled Hessian; modes outside the harmonics, m = 1, 2, 4, 5, ..., not counted). "
              "Newton its: stage 1 / stage 2 of the harmonic solve; wall s: the harmonic "
              "solve with its 3D checks.", '']
    lines += report.table(['v', 'E oblate', 'lambda_3', 'start', 'E three-fold',
                           'E3 - E oblate', 'max |psi_3|', 'level-set E (3D)', 'topology', 'index',
                           'Newton its', 'wall s'], rows)
    report.write(args.out, lines)


if __name__ == '__main__':
    main()
