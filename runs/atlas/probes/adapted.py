"""adapted.py F GAMMA ORDER: the stomatocyte at v 0.62, c0 0, eps 0.01 on the coarse
stomatocyte branch's nodes relocated for F; ORDER 2 needs quadratic.patch applied."""
import sys, time
import pfmembrane as pf
from pfmembrane.kernels import maxent
from pfmembrane.studies import atlas
pf.api.petsc(sys.argv[:1])
f, gamma, order = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
coarse = atlas.load(atlas.branch_path('runs/atlas/adapted_stomatocyte/coarse', 'stomatocyte', 0.0))
along = [pf.Result(*s) for s in coarse['shapes']]
nodes = pf.adapt(along[0], f, along=along[1:], gamma=gamma).nodes
maxent.ORDER = order  # the solve's basis only; the CVT's raster and transfer keep max-ent
sc = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=coarse['box'], branch='stomatocyte', symmetric=False)
grid = pf.Grid(sc, nodes, gamma=gamma)
t = time.time()
r = pf.solve(sc, grid, 0.01, options={'pf_start': 'sharp', 'pf_stage1_rtol': 1e-5})
pf.api.petsc().Sys.Print(order, gamma, grid.n_nodes, r.energy, r.attrs['level_set_energy'],
                         r.attrs['nu_area'], r.attrs['nu_volume'], time.time() - t)
