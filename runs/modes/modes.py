"""Stability of an axisymmetric vesicle against the perturbations psi(r, z) cos(m theta).

    python runs/modes/modes.py CKPT [--modes M] [--nev K] [--out DIR] [PETSc options]
    mpiexec -n 2 python runs/modes/modes.py CKPT ...

For m = 0 ... M (default 6) it prints the index of the mode Hessian H_m (its number of
negative eigenvalues: on the tangent space of the area, volume and moment constraints for
m = 0, from the inertia of one MUMPS factorization) and its K lowest eigenvalues (default
3) of H_m psi = lambda M_m psi, M_m the L2 mass of the 3D perturbation, so lambda is the
second variation of E - nu . (c - c0) per unit squared L2 norm of delta phi.
Eigenvalues marked `*` belong to modes more than half rigid motion
(`pfmembrane.analysis.spectra.rigid`), and the index says
how many of its negative ones are such. In m = 1 these are the translation along x and
the rotation about y: an exactly translation-invariant discretization would give them
0; here they are ~1e-4 of the first elastic eigenvalue, of either sign, set by the
discretization and above all by the support cut-off (runs/modes/README.md). In m = 0 it
is the translation along the axis, which the moment constraint does not make vanish but
pins at a finite eigenvalue (moving the vesicle then costs moving the bulk values of
phi to keep M = 0): it mixes with the shape modes odd in z. See `pfmembrane.kernels.azimuthal`
for the formulas and the treatment of the axis, `pfmembrane.parallel.stability` for the
solvers. PETSc options reach the eigensolver under `-modes_` (`-modes_eps_tol 1e-10`,
`-modes_st_mat_mumps_icntl_7 0`).

With --out DIR it writes DIR/<stem>_modes.md (the table, headed by the provenance of the
measurement: `report.provenance`) and DIR/<stem>_modes.png: the
least stable mode other than rigid motions, as the membrane phi_h = 0 displaced along its
normal by the mode (delta n = -psi cos(m theta) / |grad phi_h|) and revolved in 3D, and
psi cos(m theta) on the meridian plane theta = 0 (r > 0) and theta = pi (r < 0).

Collective; the checkpoint is read on every rank and its grid rebuilt (`pf.Grid.of`).
The time printed is that of the analysis (its set-up, then every m), without the rebuild.
CKPT and DIR are paths as given, relative to the working directory.
"""
import argparse
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.analysis import spectra as rigid_motions
from pfmembrane.cli.runner import CheckpointError


def analyse(result, grid, modes, nev, say):
    """The `Spectrum` of every m = 0 ... `modes` (`pf.stability`), printing a
    row each. Collective.

    Returns the spectra and the least stable mode other than rigid motions:
    its m, nodal chi (every rank) and eigenvalue (None, None, inf if none).
    """
    spectra = pf.stability(result, modes, nev, grid=grid)
    least = (None, None, np.inf)
    for s in spectra:
        say(row(s))
        for value, chi, rigid in zip(s.eigenvalues, s.vectors, rigid_motions.rigid(s)):
            if not rigid and value < least[2]:
                least = (s.m, chi, value)
    return spectra, least


def row(s):
    """One table row: m, index (and how many of its modes are rigid motions), the
    lowest eigenvalues (rigid ones starred), the seconds."""
    rigid = rigid_motions.rigid(s)
    values = ' '.join(f"{v:.5g}{'*' if r else ''}" for v, r in zip(s.eigenvalues, rigid))
    moving = np.count_nonzero(rigid & (s.eigenvalues < 0))
    index = f"{s.index} ({moving} rigid)" if moving else str(s.index)
    return f"| {s.m} | {index} | {values} | {s.time:.2f} |"


HEADER = ("| m | index | lowest eigenvalues | s |", "|---|---|---|---|")


def plot(result, m, chi, value, index, path):
    """Write the figure of one mode (chi at every node, psi = r^m chi_h). Not collective."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import matplotlib.tri as mtri
    from pfmembrane.analysis import levelset

    ckpt = result.checkpoint().unfolded()
    mode = pf.Result(result.nodes, chi, result.attrs).checkpoint().unfolded()
    field, chi_h = levelset.PhaseField(ckpt), levelset.PhaseField(mode)
    curve = levelset.membrane(ckpt, field=field)
    fig = plt.figure(figsize=(11, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection='3d')
    ax2 = fig.add_subplot(1, 2, 2)
    theta = np.linspace(0.0, 2 * np.pi, 97)
    radius = float(result.attrs['radius'])
    # normal displacements of the membrane, scaled to at most a fifth of R
    shifts = []
    for line in curve:
        _, grad = field(line, gradient=True)
        normal = grad / np.linalg.norm(grad, axis=1)[:, None]
        shifts.append((line, normal, -line[:, 0] ** m * chi_h(line)
                       / np.linalg.norm(grad, axis=1)))
    scale = 0.2 * radius / max([np.abs(d).max() for _, _, d in shifts] + [1e-300])
    cmap = plt.get_cmap('coolwarm')
    for line, normal, d in shifts:
        dn = scale * d[:, None] * np.cos(m * theta)[None, :]
        r = line[:, :1] + dn * normal[:, :1]
        z = line[:, 1:] + dn * normal[:, 1:]
        colours = cmap(0.5 + 0.5 * dn / (0.2 * radius))
        ax3.plot_surface(r * np.cos(theta), r * np.sin(theta), z, facecolors=colours,
                         linewidth=0, shade=False)
    rb, zb = ckpt.box
    ax3.set_xlim(-rb / 2, rb / 2)
    ax3.set_ylim(-rb / 2, rb / 2)
    ax3.set_zlim(zb / 2 - rb / 2, zb / 2 + rb / 2)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_title(f"m = {m}, lambda = {value:.4g}: membrane displaced by the mode")
    psi = ckpt.nodes[:, 0] ** m * chi_h(ckpt.nodes)
    half = mtri.Triangulation(ckpt.nodes[:, 0], ckpt.nodes[:, 1])
    top = np.abs(psi).max()
    for sign, parity in ((1.0, 1.0), (-1.0, (-1.0) ** m)):   # cos(m pi) on the left
        image = ax2.tripcolor(mtri.Triangulation(sign * half.x, half.y, half.triangles),
                              parity * psi, shading='gouraud', cmap='RdBu_r', vmin=-top,
                              vmax=top)
    for line in curve:
        for sign in (1.0, -1.0):
            ax2.plot(sign * line[:, 0], line[:, 1], color='k', linewidth=1.0)
    fig.colorbar(image, ax=ax2, label=r'$\psi\,\cos m\theta$ (M-normalized)')
    ax2.set_xlim(-rb, rb)
    ax2.set_ylim(0.0, zb)
    ax2.set_aspect('equal')
    ax2.set_xlabel('x (theta = 0: r, theta = pi: -r)')
    ax2.set_ylabel('z')
    ax2.set_title(f"E = {result.energy:.6g}, eps = {result.eps:g}, index {index}")
    fig.savefig(path, dpi=130, bbox_inches='tight')
    plt.close(fig)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog='python runs/modes/modes.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('checkpoint')
    ap.add_argument('--modes', type=int, default=6, help='highest m (default 6)')
    ap.add_argument('--nev', type=int, default=3, help='eigenvalues per m (default 3)')
    ap.add_argument('--out', help='directory of the table and the figure')
    args, petsc_args = ap.parse_known_args(argv)
    if args.modes < 0 or args.nev < 1:
        ap.error('--modes must be >= 0 and --nev >= 1')
    record = report.provenance()   # before the measurement (and before MPI starts)
    PETSc = pf.petsc(sys.argv[:1] + petsc_args)
    comm = PETSc.COMM_WORLD

    def say(text):
        PETSc.Sys.Print(text, comm=comm)

    try:
        result = pf.read(args.checkpoint, comm=comm)
    except CheckpointError as e:   # every rank reads the same verdict
        say(f"modes.py: error: {e}")
        return 2
    if not result.converged:
        say(f"warning: {args.checkpoint} is not converged: its modes are not those of an "
            "equilibrium")
    t0 = time.perf_counter()
    grid = pf.Grid.of(result, comm=comm)
    t1 = time.perf_counter()
    say(f"{args.checkpoint}: {result.attrs.get('branch', '')} E {result.energy:.8f} eps "
        f"{result.eps:g} nu_A {result.nu[0]:.6g}, {grid!r}, rebuilt in {t1 - t0:.2f} s"
        + ('; half box: only modes even about its plane' if result.scene.symmetric else ''))
    say('\n'.join(HEADER))
    spectra, (m, chi, value) = analyse(result, grid, args.modes, args.nev, say)
    elapsed = time.perf_counter() - t1
    say(f"modes: m = 0 ... {args.modes} in {elapsed:.2f} s on {comm.getSize()} rank(s)")
    if args.out and comm.getRank() == 0:
        stem = os.path.join(args.out, os.path.splitext(os.path.basename(args.checkpoint))[0])
        os.makedirs(args.out, exist_ok=True)
        with open(stem + '_modes.md', 'w') as f:
            title = f"Azimuthal modes of {os.path.basename(args.checkpoint)}"
            f.write('\n'.join([*report.header(title, record),
                               f"`{args.checkpoint}`: E {result.energy:.8f}, eps {result.eps:g}, "
                               f"{grid.n_nodes} nodes; analysis {elapsed:.2f} s on "
                               f"{comm.getSize()} rank(s)", '', *HEADER,
                               *map(row, spectra)]) + '\n')
        if chi is not None:
            plot(result, m, chi, value, spectra[m].index, stem + '_modes.png')
        print(stem + '_modes.md')
    return 0


if __name__ == '__main__':
    sys.exit(main())
