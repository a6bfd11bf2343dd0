"""The paper's discocyte (v 0.8, c0 0, eps 0.04, 6,124 nodes) pushed along its m = 2 critical
mode: the axisymmetric equilibrium, its m = 0..3 spectra, then the solve with the harmonics
m = 0, 2 (-pf_harmonics 1 -pf_dihedral 2) from phi + A r^2 chi_2 cos 2 theta, chi_2 the
critical eigenvector scaled to max |chi_2| = 1; its energy path, its energy against the
axisymmetric one's, the 3D level set's topology and energy; and the same solve from the
axisymmetric state unperturbed (A = 0), which must stay on it; the index of both; the energy
path of the iterates put back on the constraints (-pf_path). Under
mpiexec; written to runs/harmonics/discocyte.md.

    mpiexec -n 2 python runs/harmonics/discocyte.py [--amplitude 0.05] [--harmonics 1]
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
    ap.add_argument('--amplitude', type=float, default=0.05)
    ap.add_argument('--harmonics', type=int, default=1)
    ap.add_argument('--out', default=os.path.join(HERE, 'discocyte.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    rank = PETSc.COMM_WORLD.getRank()
    record = report.provenance()
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid = pf.Grid.uniform(scene, nodes=6124)
    t = time.perf_counter()
    axi = pf.solve(scene, grid, 0.04, checks=True)
    t_axi = time.perf_counter() - t
    spectra = pf.stability(axi, modes=3, nev=3)
    lowest = [s.eigenvalues[0] for s in spectra]
    chi = spectra[2].vectors[0] / np.abs(spectra[2].vectors[0]).max()
    harmonic = dataclasses.replace(scene, harmonics=args.harmonics, dihedral=2)
    runs = []
    for amplitude in (args.amplitude, 0.0):
        phi = np.zeros((len(axi.phi), args.harmonics + 1))
        phi[:, 0], phi[:, 1] = axi.phi, amplitude * chi
        start = dataclasses.replace(axi, phi=phi)
        t = time.perf_counter()
        r = pf.solve(harmonic, grid, 0.04, start=start, checks=True, options={'pf_path': True})
        seconds = time.perf_counter() - t
        runs.append((amplitude, r, seconds, pf.stability(r) if r.converged else None))
    if rank == 0:
        write(args, record, axi, t_axi, lowest, runs)


def write(args, record, axi, t_axi, lowest, runs):
    lines = report.header('The discocyte pushed along its m = 2 critical mode', record)
    lines += ["The paper's discocyte (v 0.8, c0 0, eps 0.04, 6,124 uniform nodes, 2 ranks). "
              "Lowest eigenvalue per m = 0..3 of the axisymmetric state: "
              + ', '.join(f"{v:.4g}" for v in lowest) + ". The harmonic solves carry m = "
              + ', '.join(str(2 * j) for j in range(args.harmonics + 1)) + " (cosines), start "
              "phi + A r^2 chi_2 cos 2 theta with chi_2 the m = 2 critical eigenvector (max 1). "
              "Level-set energy: the 3D surface phi_h = 0 (marching tetrahedra at steps eps/2 "
              "and eps/4), put on the constraints as the axisymmetric curve's is "
              "(`analysis.field3d.projected`), +- its change between the two steps.", '']
    rows = [["axisymmetric", "-", f"{axi.energy:.8f}", "-",
             f"{axi.attrs.get('level_set_energy', float('nan')):.6f} (curve)", '1 sphere', '-',
             '-', '-', f"{t_axi:.1f}"]]
    for amplitude, r, seconds, index in runs:
        # E on the constraints is known to about 1e-12 of itself (-pf_path)
        path = np.concatenate([[axi.energy], r.attrs['energy_path']])
        falls = bool(np.all(np.diff(path) <= 1e-12 * abs(path[0])))
        rows.append([f"m = 0, 2{', ...' if args.harmonics > 1 else ''}", f"{amplitude:g}",
                     f"{r.energy:.8f}", f"{r.energy - axi.energy:.3e}",
                     f"{r.attrs.get('level_set_energy', np.nan):.6f} +- "
                     f"{r.attrs.get('level_set_error', np.nan):.1e}",
                     r.attrs.get('topology', '-'),
                     f"{np.abs(r.phi[:, 1]).max():.4f}", '-' if index is None else index,
                     'yes' if falls else 'no', f"{seconds:.1f}"])
    lines += report.table(['state', 'A', 'E', 'E - E_axi', 'level-set E', 'topology',
                           'max |chi_2|', 'index', 'E on the constraints falls', 'wall s'],
                          rows)
    lines += ['', "index: negative eigenvalues within the solve's harmonics on the constraints' "
              "tangent space (`pf.stability` of a harmonic result: the inertia of the exact "
              "coupled Hessian); the axisymmetric state's m = 2 mode makes it 1 there. E on the "
              "constraints falls: from the axisymmetric state through every iterate of both "
              "stages, each put back on the area and volume (-pf_path), to within 1e-12 of E "
              "(how well the constraints are met). wall s: the solve with its 3D checks and its "
              "energy path, without the index."]
    amplitude, r, _, _ = runs[0]
    lines += ['', f"Energy path of the A = {amplitude:g} solve, E - E_axi at every stage-1 "
              "Newton and augmented-Lagrangian row, then every stage-2 iteration: the "
              "iterates put back on the constraints (-pf_path), then as they are (the "
              "constraints hold only at the end, so E alone need not fall):", '',
              '    ' + ' '.join(f"{e - axi.energy:.4e}" for e in r.attrs['energy_path']), '',
              '    ' + ' '.join(f"{e - axi.energy:.4e}" for e in r.attrs['energy_history']),
              '']
    report.write(args.out, lines)
    print('\n'.join(lines))


if __name__ == '__main__':
    main()
