"""The three-fold branch followed by pseudo-arclength continuation in v: from the three-fold
state at v 0.95 (the oblate at reduced c0 2.8 solved, pushed along its m = 3 critical mode,
solved with the harmonics m = 0, 3, ..., 3J; threefold.py's scene), `pf.continuation` in
the reduced volume (with harmonics it factors the exact coupled Hessian: the corrector's
Newton steps and the index from its inertia), towards the bifurcation off the
oblate near v 0.9514 (ds > 0) and away from it (ds < 0). At every point: E against the
oblate's at the same v (solved from the last one's), the signed amplitude of psi_3 and the index
within the harmonics. A supercritical pitchfork's branch ends on the oblate at the
bifurcation with amplitude ~ sqrt(v_b - v) and index 0; a subcritical one turns back at a
fold, unstable (index 1) between it and the bifurcation. Under mpiexec; written to
runs/harmonics/branch.md.

    mpiexec -n 2 python runs/harmonics/branch.py [--ds 0.002] [--steps 10] [--harmonics 2]
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
C0, EPS, RADIUS, V = 2.8, 0.04, 0.4, 0.95   # C0: the reduced 2 C0 R


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--ds', type=float, default=0.002)
    ap.add_argument('--steps', type=int, default=10)
    ap.add_argument('--harmonics', type=int, default=2)
    ap.add_argument('--out', default=os.path.join(HERE, 'branch.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    rank = PETSc.COMM_WORLD.getRank()
    record = report.provenance()
    scene = pf.Scene(reduced_volume=V, c0=C0 / (2 * RADIUS), radius=RADIUS, branch='oblate',
                     symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=6124)
    harmonic = dataclasses.replace(scene, harmonics=args.harmonics, dihedral=3)
    t = time.perf_counter()
    start = pf.solve(harmonic, grid, EPS)
    if not start.converged:
        raise SystemExit(f"the three-fold solve at v {V} did not converge: {start.message}")
    pf.stability(start)   # its index, from the coupled Hessian's inertia
    rows = [row(grid, start, pf.solve(scene, grid, EPS), 'start (solve)', time.perf_counter() - t)]
    for ds in (args.ds, -args.ds):
        oblate = None
        t = time.perf_counter()
        for point in pf.continuation(start, 'reduced_volume', ds, args.steps):
            v = point.attrs['reduced_volume']
            oblate = pf.solve(dataclasses.replace(scene, reduced_volume=v), grid, EPS,
                              start=oblate)
            rows.append(row(grid, point, oblate, f"ds {ds:+g}", time.perf_counter() - t))
            t = time.perf_counter()
            if rank == 0:
                write(args, record, rows)
    if rank == 0:
        write(args, record, rows)


def row(grid, r, oblate, how, seconds):
    """A table row of the three-fold state `r` beside the `oblate` at its v."""
    a = r.attrs
    psi3 = grid.nodes[:, 0] ** 3 * r.phi[:, 1]
    amplitude = psi3[np.argmax(np.abs(psi3))]   # signed: psi_3 -> -psi_3 is a turn by pi/3
    index = a.get('index_0', a.get('index_harmonics', -1))
    return [how, f"{a['reduced_volume']:.5f}", f"{r.energy:.8f}", f"{oblate.energy:.8f}",
            f"{r.energy - oblate.energy:.3e}", f"{amplitude:+.4f}",
            '-' if index is None or index < 0 else index, int(a.get('fold', 0)),
            a.get('stage2_iterations', '-'), f"{seconds:.1f}"]


def write(args, record, rows):
    lines = report.header('The three-fold branch by arclength continuation', record)
    lines += [f"Reduced c0 = 2 C0 R = {C0} (C0 {C0 / (2 * RADIUS):g} at R {RADIUS}), eps {EPS}, "
              "6,124 nodes of the full box (half box), 2 ranks; harmonics m = 0, 3, ..., "
              f"{3 * args.harmonics} (cosines). The start: the fresh three-fold solve at v {V}. "
              f"Then `pf.continuation(start, 'reduced_volume', ds, {args.steps})` (a branch "
              "with harmonics factors the exact coupled Hessian) for ds = "
              f"+{args.ds:g} and -{args.ds:g} (arclength in the RMS of the unknowns and v). "
              "E oblate: the axisymmetric solve at the point's v. psi_3: r^3 chi_3 at the node "
              "where its magnitude is largest (its sign flips where the branch passes the "
              "oblate onto its copy turned by pi/3). index: negative eigenvalues within the harmonics on the "
              "constraints' tangent space (the coupled factorization's inertia; the start's "
              "from the continuation's first tangent). fold: dv/ds changed sign. Newton: the "
              "corrector's factorizations. s: the point's wall time with its oblate solve.", '']
    lines += report.table(['point', 'v', 'E three-fold', 'E oblate', 'E3 - E oblate',
                           'psi_3', 'index', 'fold', 'Newton', 's'], rows)
    report.write(args.out, lines)


if __name__ == '__main__':
    main()
