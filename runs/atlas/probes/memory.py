"""memory.py Q [NODES]: resident memory of each rank after the grid, then its peak in every
0.2 s of a solve, printed when it rises by more than 50 MB. Without NODES: the stomatocyte
at v 0.62, eps 0.01 from its sharp shape on the coarse stomatocyte branch's nodes relocated
for F 100, gamma 0.4, spacing floor Q (the start of runs/atlas/adapted_stomatocyte_floor);
with NODES: the oblate at v 0.8, eps 0.04 on a uniform grid of NODES, gamma 0.4. Under
mpiexec; the solver's monitor rows place the rises among its iterations; an
address-space limit (ulimit -v) turns a spike into an error that says where it is."""
import sys
import threading
import time

import pfmembrane as pf
from pfmembrane.result import read_branch

PETSc = pf.api.petsc(sys.argv[:1])
rank = PETSc.COMM_WORLD.getRank()


def rss():
    with open('/proc/self/status') as f:
        return next(int(line.split()[1]) / 1e3 for line in f if line.startswith('VmRSS'))


def say(text, mb=None):
    print(f"rank {rank}: {text}, {rss() if mb is None else mb:.0f} MB resident", flush=True)


def watch(done, t0, step=50.0):
    """Sample the resident memory every 0.2 s; report each rise of `step` MB."""
    last = rss()
    while not done.wait(0.2):
        now = rss()
        if now > last + step:
            say(f"{time.perf_counter() - t0:.1f} s into the solve", now)
            last = now


q = float(sys.argv[1])
if len(sys.argv) > 2:
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid, eps, options = pf.Grid.uniform(scene, nodes=int(sys.argv[2]), gamma=0.4,
                                         spacing_floor=q), 0.04, {'pf_monitor': True}
else:
    along, coarse = read_branch('runs/atlas/adapted_stomatocyte/coarse/branches/stomatocyte_c0.h5')
    grid = pf.adapt(along[0], 100, along=along[1:], gamma=0.4, spacing_floor=q)
    scene = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=coarse['box'],
                     branch='stomatocyte')
    eps, options = 0.01, {'pf_start': 'sharp', 'pf_monitor': True}
say(f"grid of {grid.n_nodes} nodes built")
done = threading.Event()
sampler = threading.Thread(target=watch, args=(done, time.perf_counter()), daemon=True)
sampler.start()
pf.solve(scene, grid, eps, options=options, checks=True)
done.set()
sampler.join()
say("solved")
