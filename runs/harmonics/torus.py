"""Genus one beyond the Clifford torus: the Moebius images of the Clifford torus (Willmore
energy 2 pi^2, E = pi^2 k at C0 = 0 for every reduced volume from 0.7116 to about 0.99) are
not axisymmetric, so only harmonics reach them. The harmonics are m = 0, 1, ..., J
(-pf_dihedral 1, cosines: the mirror plane through the hole's centre; the half box: the
mirror z = zc), the moment X holding the translation across the axis. At each eps the first
J starts from the image with the scene's reduced volume (-pf_start moebius: its hole on the
axis), or with --through from the image at a smaller v walked in v to the scene's, each
next J from the last converged torus at that eps, its harmonics kept and the new ones at 0
(--no-continued: every J from the image). A torus is not continued in eps:
the coupled Newton steps from one eps's torus to the next stall. Against them, the
axisymmetric torus on the same grid and eps (from the circular tube; above v 0.84 from the
torus solved at 0.84, or with --through walked as the Moebius tori are). Under mpiexec; the
table is rewritten after every solve.

    mpiexec -n 2 python runs/harmonics/torus.py [--v 0.8] [--highest 2,4,6,8]
        [--eps 0.04,0.03] [--box 0.8,1.0] [--nodes N | --scaled] [--hessian coupled]
        [--through 0.8,0.82,0.84] [--no-continued] [--until HH:MM]
        [--out runs/harmonics/torus_eps.md]
"""
import argparse
import dataclasses
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane.paper import PAPER_EPS, paper_spacing
from pfmembrane.series import seconds_left

HERE = os.path.dirname(os.path.abspath(__file__))
PI2 = np.pi ** 2
# The circular tube starts the axisymmetric torus up to its largest reduced volume, the
# horn torus's 3 / (2 sqrt pi) = 0.846.
RING_MAX = 0.84


def nodes(box, eps=PAPER_EPS):
    """The uniform grid's node count in `box` with the paper's ratio of eps to the
    spacing (6,124 nodes in 1.5 x 2 at eps 0.04)."""
    return paper_spacing(6124, box, eps)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--v', default='0.8')
    ap.add_argument('--highest', default='2,4,6,8')
    ap.add_argument('--eps', default='0.04')
    ap.add_argument('--hessian', default='coupled', help='-pf_hessian of the harmonic solves')
    ap.add_argument('--box', default='0.8,1.0', help='Rb,Zb (the Moebius image at v 0.85 '
                    'reaches r 0.68: 0.85,1.0)')
    ap.add_argument('--nodes', type=int, default=None,
                    help="the uniform grid's node count in the full box (default: the paper's "
                    "spacing); the hole at v 0.85 needs a smaller eps than that resolves")
    ap.add_argument('--scaled', action='store_true',
                    help="each eps on its own grid, with the paper's ratio of eps to the "
                    "spacing: the trend in eps at a fixed resolution of the interface")
    ap.add_argument('--through', default='',
                    help="v1,v2,...: each J chain starts from the Moebius image at v1 and "
                    "walks in v through the others to the scene's v, each solve from the "
                    "last (from the image at v 0.85 the hole or the thin side closes: "
                    "0.8,0.82,0.84)")
    ap.add_argument('--until', default=None, help='HH:MM UTC: no solve starts after it')
    ap.add_argument('--no-continued', dest='continued', action='store_false',
                    help='every J from the Moebius image')
    ap.add_argument('--out', default=os.path.join(HERE, 'torus_eps.md'))
    args = ap.parse_args(argv)
    PETSc = pf.api.petsc(sys.argv[:1])
    mpi = PETSc.COMM_WORLD.tompi4py()
    args.ranks = mpi.Get_size()
    args.box = tuple(map(float, args.box.split(',')))
    if args.scaled and args.nodes:
        ap.error('--nodes or --scaled, not both')
    record = report.provenance()
    rows, levels = [], {}
    highest = [int(J) for J in args.highest.split(',')]
    through = [float(u) for u in args.through.split(',') if u]
    for v in map(float, args.v.split(',')):
        scene = pf.Scene(reduced_volume=v, branch='torus', c0=0.0, box=args.box, symmetric=True)
        built = None
        for eps in map(float, args.eps.split(',')):
            count = nodes(args.box, eps) if args.scaled else args.nodes or nodes(args.box)
            if count != built:
                grid, built = pf.Grid.uniform(scene, nodes=count), count
            t = time.perf_counter()
            axi, began = axisymmetric(scene, grid, eps, through)
            rows.append(row(v, eps, grid, 0, began, axi, time.perf_counter() - t))
            tori = levels[v, eps] = {0: torus_energy(axi)}
            previous = None
            for J in highest:
                if mpi.bcast(seconds_left(args.until), root=0) < 60:
                    rows.append([v, eps, grid.n_nodes, f"{grid.eps_min:.4f}", J, '',
                                 'skipped (deadline)'] + [''] * 11)
                    continue
                harmonic = dataclasses.replace(scene, harmonics=J, dihedral=1)
                began = 'Moebius'
                if previous is None:
                    # the walk in v: its tori are rows of their own
                    for u in through:
                        r, seconds = solve(dataclasses.replace(harmonic, reduced_volume=u),
                                           grid, eps, previous, args.hessian)
                        rows.append(row(u, eps, grid, J, began, r, seconds))
                        previous, began = (r, f"v {u}") if is_torus(r) else (None, 'Moebius')
                        if previous is None:
                            break
                else:
                    began = f"J = {previous.attrs['harmonics_highest']}"
                r, seconds = solve(harmonic, grid, eps, previous, args.hessian)
                rows.append(row(v, eps, grid, J, began, r, seconds))
                tori[J] = torus_energy(r)
                # a state whose hole closed continues nothing: the next starts anew
                previous = r if args.continued and is_torus(r) else None
                if mpi.Get_rank() == 0:
                    write(args, record, rows, levels)
    if mpi.Get_rank() == 0:
        write(args, record, rows, levels)


def solve(scene, grid, eps, start, hessian):
    """(result, wall seconds): a solve with harmonics from `start`, or from the
    Moebius image (-pf_start moebius) where it is None."""
    options = {'pf_hessian': hessian}
    if start is None:
        options['pf_start'] = 'moebius'
    t = time.perf_counter()
    r = pf.solve(scene, grid, eps, start=start, options=options, checks=True)
    return r, time.perf_counter() - t


def is_torus(r):
    """Whether a solve converged to one surface of genus 1."""
    return r.converged and r.attrs.get('genus') == 1


def axisymmetric(scene, grid, eps, through):
    """The axisymmetric torus and where it started: with `through`, the circular tube at
    the first of those v walked in v through the others to the scene's, as the Moebius
    tori are (at v 0.85 a step from 0.84 closes the hole at eps 0.035); else the circular
    tube, or above RING_MAX, where no ring torus of circular section has the scene's area
    and volume, the solved torus at RING_MAX."""
    if through:
        walked = None
        for u in through:
            walked = pf.solve(dataclasses.replace(scene, reduced_volume=u), grid, eps,
                              start=walked)
        return pf.solve(scene, grid, eps, start=walked, checks=True), \
            f"walked from v {through[0]}"
    if scene.reduced_volume <= RING_MAX:
        return pf.solve(scene, grid, eps, checks=True), 'circular tube'
    ring = pf.solve(dataclasses.replace(scene, reduced_volume=RING_MAX), grid, eps)
    return pf.solve(scene, grid, eps, start=ring, checks=True), f"v {RING_MAX} solved"


def torus_energy(r):
    """The level-set energy of a converged torus (genus 1), else NaN."""
    return r.attrs.get('level_set_energy', np.nan) if is_torus(r) else np.nan


def extrapolated(energies):
    """The level-set energy as J -> infinity from the tori at the last three J
    (equally spaced): Aitken's delta-squared limit, where the truncation error
    falls geometrically, by the ratio q of the last two differences (0 < q <
    1). Returns (limit, q), the limit NaN where that does not hold."""
    tori = sorted((J, e) for J, e in energies.items() if J and np.isfinite(e))[-3:]
    if len(tori) < 3 or tori[1][0] - tori[0][0] != tori[2][0] - tori[1][0]:
        return np.nan, np.nan
    (_, e0), (_, e1), (_, e2) = tori
    d1, d2 = e1 - e0, e2 - e1
    q = d2 / d1 if d1 else np.nan
    return (e2 - d2 * d2 / (d2 - d1) if 0 < q < 1 else np.nan), q


def trend(levels):
    """Rows of the trend in eps: the axisymmetric torus's level-set energy, the
    Moebius torus's at its largest J and as J -> infinity (`extrapolated`),
    each against pi^2."""
    out = []
    for (v, eps), energies in levels.items():
        axi = energies[0]
        tori = [(J, e) for J, e in sorted(energies.items()) if J and np.isfinite(e)]
        J, last = tori[-1] if tori else ('-', np.nan)
        limit, q = extrapolated(energies)
        out.append([v, eps, f"{axi:.5f}", f"{axi / PI2 - 1:+.2%}", J, f"{last:.5f}",
                    f"{last / PI2 - 1:+.2%}", f"{limit:.5f}", f"{limit / PI2 - 1:+.3%}",
                    f"{q:.3f}"])
    return out


def row(v, eps, grid, J, began, r, seconds):
    """One table row: the grid, the solve's energies against pi^2, its topology,
    the X multiplier, its wall time."""
    first = [v, eps, grid.n_nodes, f"{grid.eps_min:.4f}", J or 'axisymmetric', began]
    if not r.converged:
        return first + [f"not converged ({r.message})"] + [''] * 10 + [f"{seconds:.0f}"]
    ls = r.attrs.get('level_set_energy', np.nan)
    genus = r.attrs.get('genus', '')
    return first + [f"{r.energy:.5f}", f"{r.energy / PI2 - 1:+.2%}",
            f"{ls:.5f}", f"{ls / PI2 - 1:+.2%}", f"{r.level_set_reduced_volume:.4f}",
            r.attrs.get('topology', '-'),
            genus if genus == '' else int(genus), tube(r, 0.0), tube(r, np.pi),
            f"{r.attrs['nu_moment_x']:.4g}" if J else '',
            f"{r.attrs['stage1_iterations']}/{r.attrs['stage2_iterations']}", f"{seconds:.0f}"]


def tube(r, theta):
    """Where the nodes of the mirror plane z = zc have phi_h > 0 at angle theta:
    'r0 - r1' (the tube's section there), from the nodal harmonics,
    phi = sum_j r^m chi_j cos(m theta)."""
    nodes, phi = r.nodes, np.atleast_2d(r.phi.T).T
    m = np.asarray(r.attrs.get('harmonics', [0]))
    plane = np.abs(nodes[:, 1] - r.attrs['box'][1] / 2)
    on = plane <= plane.min() + 1e-9
    inside = nodes[on, 0][(phi[on] * nodes[on, :1] ** m * np.cos(m * theta)).sum(axis=1) > 0]
    return f"{inside.min():.3f} - {inside.max():.3f}" if len(inside) else '-'


def write(args, record, rows, levels):
    lines = report.header('Genus one: the Moebius tori against the axisymmetric torus', record)
    start = ("at each eps the first J from -pf_start moebius, each next from the last "
             "converged torus at that eps (its harmonics, the new ones at 0)"
             if args.continued else "every J from -pf_start moebius")
    if args.through:
        start += (f" (a chain's first J from the image at v {args.through.split(',')[0]}, "
                  f"walked in v through {args.through} to the scene's, the walk's tori in "
                  "rows of their own; the axisymmetric torus walked the same way from the "
                  "circular tube)")
    grids = ("at each eps its own uniform grid, with the paper's ratio of eps to the "
             "spacing (eps 0.04 on 6,124 nodes of 1.5 x 2)" if args.scaled else
             "one uniform grid " + ("at the paper's spacing" if args.nodes is None else
                                    f"of {args.nodes} nodes in the full box"))
    lines += [f"C0 = 0, R 0.4, box {args.box[0]:g} x {args.box[1]:g} as a half box, "
              f"{grids} (nodes: those of the half box, solved; eps_min: the smallest eps "
              "the grid resolves), "
              f"{args.ranks} rank(s); harmonics m = 0, 1, ..., J, "
              f"{start}, -pf_hessian {args.hessian}. pi^2 = {PI2:.6f} is the least "
              "energy of genus one at these v (sharp, exact). Level-set E: the energy of the "
              "surface phi_h = 0 as it is (the curve of revolution for the axisymmetric torus, "
              "the 3D surface with harmonics), a torus not being put on the constraints: at C0 "
              "= 0 its energy depends on its reduced volume alone, near the Clifford torus's "
              "conformal family only to second order (level set v: the reduced volume of "
              "phi_h = 0, which the phase field's diffuse volume and area leave below the "
              "scene's). nu_X: the multiplier of "
              "the moment across the axis; it vanishes where the translation is a symmetry "
              "of the discrete problem, so it measures what the truncation at J costs. Tube: "
              "the nodes of the mirror plane z = zc where the nodal phi > 0 at theta = 0 and "
              "pi, the section of the tube on either side of the axis; the start's is "
              "lopsided, its hole's centre on the axis.", '']
    lines += report.table(['v', 'eps', 'nodes', 'eps_min', 'J', 'from', 'E', 'E / pi^2 - 1',
                           'level-set E', 'vs pi^2', 'level set v', 'topology', 'genus',
                           'tube at theta = 0 (r)', 'at theta = pi', 'nu_X', 'Newton its (1/2)',
                           'wall s'], rows)
    lines += ['', "The trend in eps: the level-set energies of the axisymmetric torus and of "
              "the Moebius torus at its largest J, and the latter as J -> infinity, Aitken's "
              "delta-squared limit from the last three J (the truncation error falling "
              "geometrically by q, the ratio of the last two differences; NaN unless 0 < q "
              "< 1). Each the 3D surface phi_h = 0 as it is.", '']
    lines += report.table(['v', 'eps', 'axisymmetric level-set E', 'vs pi^2', 'J',
                           'Moebius level-set E', 'vs pi^2', 'J -> infinity', 'vs pi^2', 'q'],
                          trend(levels))
    report.write(args.out, lines)


if __name__ == '__main__':
    main()
