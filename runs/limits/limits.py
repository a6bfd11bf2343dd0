"""Two exact limits as eps falls (runs/limits/notes.md):

    python runs/limits/limits.py [--np 2] [--out runs/limits] [--only clifford]

the Clifford torus (options/limits/clifford.opts: E -> pi^2 k, both multipliers -> 0,
radii in ratio 1 : sqrt 2) and symmetric budding (two spheres of radius R / sqrt 2 with H
= C0 at v = 1 / sqrt 2, C0 = sqrt 2 / R: E -> 0), and the split (`--only split`): two
spheres apart, at the least reduced volume where the phase field's two spheres exist. A
Clifford row is the run `python -m pfmembrane -options_file SCENE -pf_nodes N -pf_eps EPS`
would make, from the scene's own start, the rows of one grid on that grid built once.
Budding is reached by continuation in C0 on the half box (`budded`): the two touching
spheres started from directly do not converge (runs/limits/notes.md). At v = 1 / sqrt 2
the phase field cannot split: two tanh spheres with the area A0 hold more than V0
(`analysis.spheres.split_volume`); at the least volume they do hold, a start of two
spheres SPLIT_GAP eps apart goes to two spheres of radius near R / sqrt 2, reported after
stage 1: apart, they feel each other only through terms in exp(-gap / eps), so no Newton
iteration settles their distance. All in one process on NP ranks (started under mpiexec
if need be); existing checkpoints are reused. From any working directory: the options
file is the repository's, --out defaults to its runs/limits. The level set of phi_h is
measured by `analysis.levelset`: its topology, the torus's own energy (`loop_energy`) and
radii, and the upper lobe's half height, largest r and neck radius (`lobe`).
"""
import argparse
import dataclasses
import math
import os
import sys
import time

import numpy as np

from pfmembrane import series
from pfmembrane.analysis.spheres import spheres_phi, split_volume
from pfmembrane.paper import SCENE
from pfmembrane.report import header, provenance

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# (eps, nodes) of each limit, the grid resolving the smallest eps on its box.
# Budding: nodes are the spacing of that many in the paper box.
ROWS = {'clifford': [(0.04, 6124), (0.03, 6124), (0.02, 6124), (0.015, 10000)],
        'budding': [(0.04, 6124), (0.03, 12000), (0.02, 22000), (0.015, 40000)],
        'split': [(0.04, 6124), (0.03, 12000), (0.02, 22000)]}
CLIFFORD = os.path.join(ROOT, 'options', 'limits', 'clifford.opts')
RADIUS = SCENE['radius']
BUD_V, BUD_C0 = 1 / math.sqrt(2), math.sqrt(2) / RADIUS
# The budding path: the prolate's sharp shape at C0 = BUD_FROM (one body, a wide neck), in
# a half box that holds it and the two spheres with 5 eps to spare at eps 0.04.
BUD_FROM, BUD_BOX, BUD_DS = 1.25, (0.5, 2.0), 0.25
SPLIT_GAP = 6.0  # eps between the two spheres of the split's start
# The split ends with stage 1 (see the docstring); its multipliers start at the limit's, 0.
SPLIT_OPTIONS = {'pf_stage1_rtol': 1e-6, 'stage2_snes_max_it': 0}


def clifford(eps, nodes, out, cache):
    """The checkpoint of one Clifford row, solved unless it exists."""
    from pfmembrane.cli import runner
    path = os.path.join(out, f"clifford_n{nodes}_eps{eps:g}.h5")
    return runner.solved(CLIFFORD, ['-pf_nodes', str(nodes), '-pf_eps', str(eps)], path,
                       cache).checkpoint()


def budded(eps, nodes, out):
    """The checkpoint of one budding row: the prolate at v = 1 / sqrt 2 and C0 = BUD_FROM
    from its sharp shape, `pf.continuation` in C0 until it passes sqrt 2 / R, then the
    solve at sqrt 2 / R from that point; read back if it exists. Collective; the
    checkpoint's `continuation_points` counts the points on the way and its
    `wall_time` is the whole path's."""
    import pfmembrane as pf
    from pfmembrane.paper import paper_spacing
    path = os.path.join(out, f"budding_n{nodes}_eps{eps:g}.h5")
    if os.path.exists(path):
        return pf.read(path).checkpoint()
    t0 = time.perf_counter()
    scene = pf.Scene(reduced_volume=BUD_V, c0=BUD_FROM, radius=RADIUS, box=BUD_BOX,
                     branch='prolate', symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=paper_spacing(nodes, BUD_BOX))
    last = pf.solve(scene, grid, eps, options={'pf_start': 'sharp'}, checks=True)
    points = 0
    for last in pf.continuation(last, 'c0', BUD_DS, 100, ds_max=4 * BUD_DS, checks=True):
        points += 1
        if last.attrs['c0'] > BUD_C0:
            break
    else:
        raise RuntimeError(f"budding at eps {eps:g}: the continuation in C0 stopped at "
                           f"{last.attrs['c0']:g}, short of {BUD_C0:g}")
    res = pf.solve(dataclasses.replace(scene, c0=BUD_C0), grid, eps, start=last,
                   options={'pf_stage1': 'none'}, checks=True)
    res.attrs.update(continuation_points=points, wall_time=time.perf_counter() - t0)
    res.save(path)
    return res.checkpoint()


def split(eps, nodes, out):
    """The checkpoint of one split row: two tanh spheres of radius `split_volume`'s rho
    (`analysis.spheres`),
    SPLIT_GAP eps apart about the mirror plane, solved at v = `split_volume` and
    C0 = sqrt 2 / R with SPLIT_OPTIONS; read back if it exists. Collective."""
    import pfmembrane as pf
    from pfmembrane.paper import paper_spacing
    path = os.path.join(out, f"split_n{nodes}_eps{eps:g}.h5")
    if os.path.exists(path):
        return pf.read(path).checkpoint()
    v, rho = split_volume(eps, RADIUS)
    scene = pf.Scene(reduced_volume=v, c0=BUD_C0, radius=RADIUS, box=BUD_BOX,
                     branch='budded', symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=paper_spacing(nodes, BUD_BOX))
    height = rho + 0.5 * SPLIT_GAP * eps
    phi = spheres_phi(grid.nodes, [rho, rho], np.array([-height, height]), scene.zc, eps)
    start = pf.Result(grid.nodes, phi, dict(eps=eps, symmetric=1, converged=1,
                                            nu_area=0.0, nu_volume=0.0))
    res = pf.solve(scene, grid, eps, start=start, options=SPLIT_OPTIONS, checks=True)
    res.save(path)
    return res.checkpoint()


def lobe(curve, zc):
    """Half the height, the largest r and the neck radius (0 if split) of the part of
    phi_h = 0 above the mirror plane z = zc."""
    up = np.vstack([piece[piece[:, 1] >= zc] for piece in curve])
    near = np.abs(up[:, 1] - zc) < 1e-2 * np.ptp(up[:, 1])
    return 0.5 * float(np.ptp(up[:, 1])), float(up[:, 0].max()), \
        float(up[near, 0].min()) if near.any() else 0.0


def measure(ckpt):
    """Topology of phi_h = 0, each torus's energy and (tube, centre-line) radii, and the
    `lobe` above the box's mid-plane."""
    from pfmembrane.analysis import levelset
    field = levelset.PhaseField(ckpt)
    curve = levelset.level_set(ckpt, field=field)
    shape = levelset.topology(curve, ckpt.box)
    tori = [levelset.loop_energy(ckpt, piece, field) for piece in curve
            if piece[:, 0].min() > 1e-3 * max(ckpt.box)]
    return shape['label'], tori, lobe(curve, 0.5 * ckpt.box[1])


TITLES = {'clifford': 'The Clifford torus as eps falls',
          'budding': 'Symmetric budding as eps falls',
          'split': 'The split of two spheres as eps falls',
          None: 'Exact limits as eps falls: the Clifford torus, symmetric budding, the split'}


def main(argv=None):
    record = provenance()  # before anything is measured
    ap = argparse.ArgumentParser(prog='python runs/limits/limits.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--np', type=int, default=2)
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'limits'))
    ap.add_argument('--only', choices=sorted(ROWS), help='one limit only')
    args = ap.parse_args(argv)
    series.ensure_ranks(args.np, __file__, sys.argv[1:])
    from pfmembrane.cli import runner
    from mpi4py import MPI
    cache, root = runner.Cache(), MPI.COMM_WORLD.Get_rank() == 0
    os.makedirs(args.out, exist_ok=True)
    lines = [*header(TITLES[args.only], record),
             f"{MPI.COMM_WORLD.Get_size()} MPI ranks, {os.cpu_count()} cores. Regenerate: "
             "`make limits` (`python runs/limits/limits.py`).", '']
    for name in [args.only] if args.only else ROWS:
        rows = []
        for eps, nodes in ROWS[name]:
            ck = (clifford(eps, nodes, args.out, cache) if name == 'clifford' else
                  {'budding': budded, 'split': split}[name](eps, nodes, args.out).unfolded())
            a = ck.attrs
            label, tori, lobed = measure(ck) if root else ('', [], (math.nan,) * 3)
            rows.append((eps, nodes, a, label, tori, lobed))
        if name == 'clifford':
            lines += ['## The Clifford torus: E -> pi^2 = 9.869604, nu -> 0, b / a -> sqrt 2', '',
                      '| nodes | eps | E | E / pi^2 - 1 | nu_A | nu_V | phi_h = 0 | its (1+2) | converged '
                      '| wall s | level-set E | vs pi^2 | tube a | centre b | b / a |',
                      '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
            for eps, nodes, a, label, tori, _ in rows:
                e, (tube, centre) = tori[0] if len(tori) == 1 else (math.nan, (math.nan,) * 2)
                lines.append(
                    f"| {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | "
                    f"{100 * (a['energy'] / math.pi ** 2 - 1):+.2f}% | {a['nu_area']:.4f} | "
                    f"{a['nu_volume']:.3f} | {label} | {int(a['stage1_iterations'])}+"
                    f"{int(a['stage2_iterations'])} | {int(a['converged'])} | {a['wall_time']:.1f} | {e:.5f} | "
                    f"{100 * (e / math.pi ** 2 - 1):+.3f}% | {tube:.4f} | {centre:.4f} | "
                    f"{centre / tube:.4f} |")
        elif name == 'split':
            target = RADIUS / math.sqrt(2)
            lines += ['## The split: two spheres apart at v = 1 / sqrt 2 (1 + (pi^2 / 2 + 3) eps^2 / R^2)',
                      '', f'C0 = sqrt 2 / R, half box {BUD_BOX[0]:g} x {BUD_BOX[1]:g}, from two tanh '
                      f'spheres {SPLIT_GAP:g} eps apart; stage 1 only (stage-1 relative constraint '
                      f"residual {SPLIT_OPTIONS['pf_stage1_rtol']:g}), so converged is 0.", '',
                      '| nodes | eps | v | v sqrt 2 - 1 | E | nu_A | nu_V | phi_h = 0 | stage-1 its '
                      '| wall s | lobe half height | vs R/sqrt2 | lobe largest r | vs R/sqrt2 |',
                      '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
            for eps, nodes, a, label, _, (half, width, _) in rows:
                v = a['reduced_volume']
                lines.append(
                    f"| {int(a['n_nodes'])} | {eps:g} | {v:.5f} | {100 * (v * math.sqrt(2) - 1):+.2f}% | "
                    f"{a['energy']:.5f} | {a['nu_area']:.4f} | {a['nu_volume']:.3f} | {label} | "
                    f"{int(a['stage1_iterations'])} | {a['wall_time']:.1f} | {half:.5f} | "
                    f"{100 * (half / target - 1):+.2f}% | {width:.5f} | "
                    f"{100 * (width / target - 1):+.2f}% |")
        else:
            target = RADIUS / math.sqrt(2)
            lines += [f'## Symmetric budding: two spheres of radius R / sqrt 2 = {target:.5f}, E -> 0',
                      '', 'v = 1 / sqrt 2, C0 = sqrt 2 / R, half box '
                      f'{BUD_BOX[0]:g} x {BUD_BOX[1]:g}, reached by continuation in C0 from '
                      f'{BUD_FROM:g}; nodes of the paper-box spacing given in `ROWS`.', '',
                      '| nodes | eps | E | nu_A | nu_V | phi_h = 0 | points in C0 | converged '
                      '| wall s | lobe half height | vs R/sqrt2 | lobe largest r | vs R/sqrt2 '
                      '| neck r | neck r / eps |',
                      '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
            for eps, nodes, a, label, _, (half, width, neck) in rows:
                lines.append(
                    f"| {int(a['n_nodes'])} | {eps:g} | {a['energy']:.5f} | {a['nu_area']:.4f} | "
                    f"{a['nu_volume']:.3f} | {label} | {int(a['continuation_points'])} | "
                    f"{int(a['converged'])} | {a['wall_time']:.1f} | {half:.5f} | "
                    f"{100 * (half / target - 1):+.2f}% | {width:.5f} | "
                    f"{100 * (width / target - 1):+.2f}% | {neck:.4f} | {neck / eps:.2f} |")
        lines.append('')
    if root:
        table = os.path.join(args.out, f"limits{'_' + args.only if args.only else ''}.md")
        with open(table, 'w') as f:
            f.write('\n'.join(lines))
        print('\n'.join(lines))
        print(table)
    return 0


if __name__ == '__main__':
    sys.exit(main())
