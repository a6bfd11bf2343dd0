"""Energies to the last digit of one scene of each kind the engine serves, on the public API
alone: the paper's discocyte and dumbbell, the half-box adaptive discocyte sequence (grids O1,
O11, O12, O13 of Table B.6), the oblate branch from v 0.95 down past 0.75 by arclength, the
m = 0..4 spectra of the eps 0.06 discocyte and the Clifford torus at eps 0.04.

    mpiexec -n 2 python runs/engine/equivalence.py > OUT.txt

Run at two commits (`git worktree add DIR COMMIT`, then PYTHONPATH=DIR), the outputs
compared by `compare.py`. The first lines (`#`) name the code, the machine and its load.
"""
import datetime
import os
import platform
import subprocess
import sys

import pfmembrane as pf

quiet = {'pf_monitor': False}


def line(name, value):
    pf.api.petsc().Sys.Print(f"{name:40s} {value!r}")


def paper(branch):
    scene = pf.Scene(reduced_volume=0.8, radius=0.4, box=(1.5, 2.0), branch=branch)
    grid = pf.Grid.uniform(scene, nodes=6124, gamma=0.8)
    return scene, grid, pf.solve(scene, grid, eps=0.04, checks=False)


def half_sequence():
    scene = pf.Scene(reduced_volume=0.8, radius=0.4, box=(1.5, 2.0), branch='oblate',
                     symmetric=True)
    grid = pf.Grid.uniform(scene, nodes=6124, gamma=0.5)
    res = pf.solve(scene, grid, eps=0.04, checks=False)
    yield 'O1 eps 0.04', res
    previous = {}
    for f, eps_list in ((10, (0.04, 0.03)), (100, (0.03, 0.025, 0.02)),
                        (1000, (0.025, 0.02, 0.015))):
        start = res if f == 10 else previous[eps_list[0]]
        grid = pf.adapt(start, f)
        res, previous = None, {}
        for i, eps in enumerate(eps_list):
            opts = {'pf_stage1': 'none'} if i == 0 or f == 1000 else None
            res = pf.solve(scene, grid, eps=eps, start=start if i == 0 else res,
                           options=opts, checks=False)
            previous[eps] = res
            yield f"O1{len(str(f)) - 1} f {f} eps {eps:g}", res
    grid = pf.Grid.of(res, gamma=0.4)
    yield 'O13 gamma 0.4 eps 0.01', pf.solve(scene, grid, eps=0.01, start=res,
                                             options={'pf_stage1': 'none'}, checks=False)


def header():
    """The code version, the date, the machine and its load, as `#` lines."""
    here = os.path.dirname(os.path.abspath(pf.__file__))
    git = ['git', '-C', here]
    commit = subprocess.run([*git, 'rev-parse', '--short', 'HEAD'], capture_output=True,
                            text=True).stdout.strip()
    dirty = subprocess.run([*git, 'status', '--porcelain', '--untracked-files=no'],
                           capture_output=True, text=True).stdout.strip()
    cpu = next((line.split(':', 1)[1].strip() for line in open('/proc/cpuinfo')
                if line.startswith('model name')), platform.processor())
    ranks = pf.api.petsc().COMM_WORLD.getSize()
    for line in (f"code {commit}{' (modified)' if dirty else ''} at {here}",
                 f"date {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
                 f"machine {os.cpu_count()} cores, {cpu}; load {os.getloadavg()[0]:.2f} at start",
                 f"command mpiexec -n {ranks} python {' '.join(sys.argv)}"):
        pf.api.petsc().Sys.Print('# ' + line)


def main():
    header()
    which = sys.argv[1:] or ['paper', 'sequence', 'branch', 'spectra', 'clifford']
    if 'paper' in which:
        for branch in ('oblate', 'prolate'):
            res = paper(branch)[2]
            line(f"{branch} v 0.8 eps 0.04 E", res.energy)
            line(f"{branch} v 0.8 eps 0.04 nu_A", float(res.nu[0]))
    if 'sequence' in which:
        for name, res in half_sequence():
            line(f"half {name} E", res.energy)
    if 'branch' in which:
        scene = pf.Scene(reduced_volume=0.95, radius=0.4, box=(1.5, 2.0), branch='oblate')
        grid = pf.Grid.uniform(scene, nodes=6124)
        res = pf.solve(scene, grid, eps=0.04, checks=False)
        line("oblate branch v 0.95 E", res.energy)
        for p in pf.continuation(res, 'reduced_volume', ds=-0.02, steps=40, checks=False):
            v = p.attrs['reduced_volume']
            line(f"oblate branch v {v:.12f} E", p.energy)
            if v < 0.75:
                break
    spectra = {'spectra': ('discocyte eps 0.06', dict(reduced_volume=0.8, box=(1.5, 2.0),
                                                      branch='oblate'), 3000, 0.06),
               'clifford': ('clifford eps 0.04', dict(reduced_volume=0.7116374975, box=(0.8, 1.0),
                                                      branch='torus'), 6124, 0.04)}
    for key, (name, scene, nodes, eps) in spectra.items():
        if key in which:
            scene = pf.Scene(radius=0.4, **scene)
            res = pf.solve(scene, pf.Grid.uniform(scene, nodes=nodes), eps=eps, checks=False)
            line(f"{name} E", res.energy)
            for m, s in enumerate(pf.stability(res, modes=4)):
                line(f"{name} m {m} lambda", [float(v) for v in s.eigenvalues])

if __name__ == '__main__':
    main()
