"""memory.py Q [NODES]: resident memory of each rank after the grid and at every stage-1
Newton iteration of a solve. Without NODES: the stomatocyte at v 0.62, eps 0.01 from its
sharp shape on the coarse stomatocyte branch's nodes relocated for F 100, gamma 0.4,
spacing floor Q (the start of runs/atlas/adapted_stomatocyte_floor); with NODES: the
oblate at v 0.8, eps 0.04 on a uniform grid of NODES, gamma 0.4. Under mpiexec; an
address-space limit (ulimit -v) turns a spike into an error that says where it is."""
import sys

import pfmembrane as pf
from pfmembrane.parallel import solver
from pfmembrane.result import read_branch

PETSc = pf.api.petsc(sys.argv[:1])
rank = PETSc.COMM_WORLD.getRank()


def rss():
    with open('/proc/self/status') as f:
        return next(int(line.split()[1]) / 1e3 for line in f if line.startswith('VmRSS'))


def say(text):
    PETSc.Sys.Print(f"rank {rank}: {text}, {rss():.0f} MB resident", comm=PETSc.COMM_SELF)


row = solver.Solver.row


def watched(self, *args, **kwargs):
    say(f"{args[0]} {args[1]} ({self.factorizations} factorizations)")
    return row(self, *args, **kwargs)


solver.Solver.row = watched
q = float(sys.argv[1])
if len(sys.argv) > 2:
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid, eps, options = pf.Grid.uniform(scene, nodes=int(sys.argv[2]), gamma=0.4,
                                         spacing_floor=q), 0.04, {}
else:
    along, coarse = read_branch('runs/atlas/adapted_stomatocyte/coarse/branches/stomatocyte_c0.h5')
    grid = pf.adapt(along[0], 100, along=along[1:], gamma=0.4, spacing_floor=q)
    scene = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=coarse['box'],
                     branch='stomatocyte')
    eps, options = 0.01, {'pf_start': 'sharp'}
say(f"grid of {grid.n_nodes} nodes built")
pf.solve(scene, grid, eps, options=options, checks=True)
say("solved")
