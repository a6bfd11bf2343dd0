"""Cost of the harmonics: the oblate at reduced c0 = 2 C0 R = 2.8, v 0.95 (C0 3.5 at R
0.4, half box, eps 0.04, 6,124 nodes of the full box: the three-fold scene of
threefold.py), solved axisymmetric and with the cosine harmonics m = 0, 3, ..., 3J for each
J of --harmonics (-pf_dihedral 3; J = 4: five harmonics), each from its fresh start (the
axisymmetric solve, then the push along the m = 3 critical mode: the largest J with each
-pf_push of --push, curved (the default: along the branch to its leading-order amplitude)
and straight (by -pf_perturb 0.02), the others with the default), in turn, REPEAT times, in
one sitting: wall time (the solve without its checks), peak memory, Newton and Krylov
iterations, factorizations, the energy; and the largest set with the default push again
with the block preconditioner assembled and factored at every Newton step (-pf_refresh 0),
then also with GMRES to 1e-10 instead of the default 1e-6. A scene whose harmonic solve
ends at a non-axisymmetric equilibrium near its start, so that its wall measures the
solver: the paper's discocyte with m up to 8 descends far from its m = 2 push (this page's
version of 22707a7 in the history: not converged in 1041 s, E 9.5908 against the
axisymmetric 9.6003).
Under mpiexec; written to runs/harmonics/cost.md.

    mpiexec -n 2 python runs/harmonics/cost.py [--repeat 2] [--harmonics 2,4]
        [--push curved,straight]
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
VARIANTS = (('-pf_refresh 0', {'pf_refresh': 0}),
            ('-pf_refresh 0, Krylov rtol 1e-10',
             {'pf_refresh': 0, 'stage1_ksp_rtol': 1e-10, 'stage2_ksp_rtol': 1e-10}))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeat', type=int, default=2)
    ap.add_argument('--harmonics', default='2,4')
    ap.add_argument('--push', default='curved,straight',
                    help='-pf_push of the largest set: how the start leaves the axisymmetric state')
    ap.add_argument('--out', default=os.path.join(HERE, 'cost.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    record = report.provenance()
    scene = pf.Scene(reduced_volume=0.95, c0=3.5, radius=0.4, branch='oblate', symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=6124)
    scenes = {'axisymmetric': (scene, {})}
    highest = [int(J) for J in args.harmonics.split(',')]
    for J in highest:
        for push in args.push.split(',') if J == max(highest) else ['curved']:
            scenes[f"m = 0, 3, ..., {3 * J} ({J + 1} cosines), {push} push"] = (
                dataclasses.replace(scene, harmonics=J, dihedral=3), {'pf_push': push})
    # the trade of the solver's defaults, on the largest set: the preconditioner new at
    # every Newton step, and with it GMRES to 1e-10
    J = max(highest)
    for label, options in VARIANTS:
        scenes[f"m = 0, 3, ..., {3 * J} ({J + 1} cosines), curved push, {label}"] = (
            dataclasses.replace(scene, harmonics=J, dihedral=3), options)
    times = {name: [] for name in scenes}
    last, peak = {}, {}
    for _ in range(args.repeat):
        for name, (s, options) in scenes.items():
            t = time.perf_counter()
            r = pf.solve(s, grid, 0.04, options=options)
            times[name].append(time.perf_counter() - t)
            last[name] = r
            # the resident set's peak only grows: the first round's is each solve's own
            peak.setdefault(name, r.attrs['peak_rss_mb'])
    if PETSc.COMM_WORLD.getRank() == 0:
        write(args, record, times, last, peak)


def write(args, record, times, last, peak):
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
                     f"{a['factorizations']}", f"{peak[name]:.0f}",
                     f"{a['start_push']:.3f}" if 'start_push' in a else ''])
    lines = report.header('Cost of the harmonics on the three-fold scene', record)
    lines += ["The oblate at reduced c0 2.8 (C0 3.5, R 0.4), v 0.95, eps 0.04, half box, 6,124 "
              "uniform nodes of the full box (the paper's spacing), 2 ranks, each solve from "
              "its fresh start (with harmonics: the axisymmetric solve, then the push along the "
              "m = 3 critical mode, curved (-pf_push curved, the default: along the branch's "
              "centre manifold to second order, to its leading-order amplitude) or straight "
              "(by -pf_perturb 0.02); both in its wall; push: the start's largest |psi_3|); "
              "the runs alternate, "
              f"{args.repeat} of each. Wall: `pf.solve` without the phase-field checks. "
              "Krylov per Newton step: stage 2's GMRES iterations over its Newton steps (the "
              "axisymmetric stage 2 factors its exact Jacobian). Factorizations: both stages' "
              "of the harmonic solve (the axisymmetric one's not counted). Peak memory: the "
              "largest resident set of the ranks, in the first round (axisymmetric, then each "
              "set in turn: a peak only grows).", '']
    lines += report.table(['solve', 'converged', 'E', 'wall s (each run)', 'wall / axisymmetric',
                           'stage 1 / 2 s', 'Newton its (stage 1 / 2)',
                           'Krylov its per Newton step', 'factorizations', 'peak MB', 'push'],
                          rows)
    report.write(args.out, lines)
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
