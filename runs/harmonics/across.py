"""Rotation invariance: a prolate lying across the axis (its long axis along x) at v 0.95 and
0.9, eps 0.04, with the cosine harmonics m = 0, 2, ..., 2J about z (-pf_dihedral 2, half box
in z), against the axisymmetric prolate (long axis along z) at the same eps and spacing (the
paper's: 6,124 nodes on 1.5 x 2), on one box that holds both. The first J starts from the
triaxial start (-pf_start across), each next from the last J that converged across the axis,
its harmonics kept and the new ones at 0 (--no-continued: every J from the triaxial start).
With too few harmonics to hold the shape across the axis the solve relaxes to another
equilibrium (the oblate, whose theta-average it shares), and a start from there would stay.
Under mpiexec; the table is rewritten after every solve to runs/harmonics/across.md.

    mpiexec -n 2 python runs/harmonics/across.py [--highest 1,2,3,4,6] [--v 0.95,0.9]
        [--until HH:MM] [--hessian block|coupled] [--no-continued] [--out runs/harmonics/across.md]
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
BOX = (0.75, 1.5)
NODES = round(6124 * BOX[0] * BOX[1] / (1.5 * 2.0))  # the paper's spacing
EPS = 0.04


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--highest', default='1,2,3,4,6')
    ap.add_argument('--v', default='0.95,0.9')
    ap.add_argument('--until', default=None, help='HH:MM UTC: no solve starts after it')
    ap.add_argument('--hessian', default='block', help='-pf_hessian of the solves across')
    ap.add_argument('--continued', action=argparse.BooleanOptionalAction, default=True,
                    help='start each J from the last converged J (--no-continued: every J '
                    'from the triaxial start)')
    ap.add_argument('--out', default=os.path.join(HERE, 'across.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    rank = PETSc.COMM_WORLD.getRank()
    record = report.provenance()
    rows, axis = [], {}
    for v in map(float, args.v.split(',')):
        scene = pf.Scene(reduced_volume=v, branch='prolate', box=BOX, symmetric=True)
        grid = pf.Grid.uniform(scene, nodes=NODES)
        t = time.perf_counter()
        axi = pf.solve(scene, grid, EPS, checks=True)
        axis[v] = (axi.energy, axi.attrs.get('level_set_energy', np.nan),
                   time.perf_counter() - t)
        previous = None
        for J in map(int, args.highest.split(',')):
            if PETSc.COMM_WORLD.tompi4py().bcast(seconds_left(args.until), root=0) < 60:
                rows.append([v, J, 'skipped (deadline)'] + [''] * 7)
                continue
            harmonic = dataclasses.replace(scene, harmonics=J, dihedral=2)
            options = {'pf_hessian': args.hessian}
            if previous is None:
                options['pf_start'] = 'across'
            t = time.perf_counter()
            r = pf.solve(harmonic, grid, EPS, start=previous, options=options, checks=True)
            seconds = time.perf_counter() - t
            began = 'triaxial' if previous is None else f"J = {previous.attrs['harmonics_highest']}"
            if args.continued and r.converged and shape(r).endswith('across'):
                previous = r
            rows.append([v, J, f"{r.energy:.6f}" if r.converged else f"not converged ({r.message})",
                         f"{(r.energy / axi.energy - 1) * 100:+.3f}%",
                         f"{r.attrs.get('level_set_energy', np.nan):.5f}",
                         r.attrs.get('topology', '-'), shape(r), began, f"{seconds:.0f}",
                         f"{r.attrs['stage1_iterations']}/{r.attrs['stage2_iterations']}"])
            if rank == 0:
                write(args, record, rows, axis)
    if rank == 0:
        write(args, record, rows, axis)


def shape(r):
    """Which way the 3D level set is long: its extent along x against z (from the
    harmonics on the nodes: phi_h > 0 along the x axis, theta = 0, and along z)."""
    # phi_h at theta = 0: sum_j r^m chi_j (every cos m theta = 1)
    cos0 = (r.phi * r.nodes[:, :1] ** np.asarray(r.attrs['harmonics'])).sum(axis=1)
    inside = r.nodes[cos0 > 0]
    if not len(inside):
        return '-'
    x, z = inside[:, 0].max(), inside[:, 1].max() - r.attrs['box'][1] / 2
    return f"x {x:.3f}, z {z:.3f}: {'across' if x > z else 'along z'}"


def write(args, record, rows, axis):
    lines = report.header('A prolate across the axis against the axisymmetric prolate', record)
    start = ("the first J from the triaxial start, each next from the last converged J (its "
             "harmonics, the new ones at 0)" if args.continued
             else "every J from the triaxial start")
    lines += [f"eps {EPS}, box {BOX[0]} x {BOX[1]} (half box z >= {BOX[1] / 2}), {NODES} nodes "
              "of the full box (the paper's spacing), 2 ranks. Harmonics m = 0, 2, ..., 2J "
              f"(cosines), {start}, -pf_hessian {args.hessian}. Level-set E: the 3D surface put on "
              "the constraints (NaN where no level of phi_h has the scene's reduced volume). "
              "Half-lengths: the farthest node with phi_h > 0 along x (theta = 0) and along "
              "z from the centre.", '',
              'Axisymmetric prolate (long axis along z) on the same grid:', '']
    lines += report.table(['v', 'E', 'level-set E (curve)', 'wall s'],
                          [[v, f"{e:.6f}", f"{ls:.5f}", f"{s:.1f}"]
                           for v, (e, ls, s) in axis.items()])
    lines += ['', 'Across the axis:', '']
    lines += report.table(['v', 'J', 'E', 'E / E_axi - 1', 'level-set E (3D)', 'topology',
                           'half-lengths (nodes with phi > 0)', 'from', 'wall s',
                           'Newton its (stage 1/2)'], rows)
    report.write(args.out, lines)


if __name__ == '__main__':
    main()
