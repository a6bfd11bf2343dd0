"""adapted.py F GAMMA [Q [ORDER]]: the stomatocyte at v 0.62, c0 0, eps 0.01 on the coarse
stomatocyte branch's nodes relocated for F. Q > 0: beta_a = GAMMA / max(h_a, h_Q)^2 (h_a
the smoothed nodal spacing, h_Q its Q-quantile) instead of GAMMA / h_a^2, one locality
over the finest nodes, the interfaces' band (`pf.Grid`'s spacing_floor). ORDER 2 needs
quadratic.patch applied, which reads it from PFMEMBRANE_MAXENT_ORDER for the whole run
(the CVT's raster and transfer included)."""
import sys, time
import numpy as np
import pfmembrane as pf
import os
from pfmembrane.result import read_branch
pf.api.petsc(sys.argv[:1])
f, gamma = float(sys.argv[1]), float(sys.argv[2])
q, order = (float(sys.argv[3]) if len(sys.argv) > 3 else 0.0), (int(sys.argv[4]) if len(sys.argv) > 4 else 1)
along, coarse = read_branch('runs/atlas/adapted_stomatocyte/coarse/branches/stomatocyte_c0.h5')
nodes = pf.adapt(along[0], f, along=along[1:], gamma=gamma).nodes
if order != int(os.environ.get('PFMEMBRANE_MAXENT_ORDER', '1')):
    sys.exit(f'ORDER {order}: apply quadratic.patch and set PFMEMBRANE_MAXENT_ORDER={order}')
sc = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=coarse['box'], branch='stomatocyte', symmetric=False)
grid = pf.Grid(sc, nodes, gamma=gamma, spacing_floor=q)
pf.api.petsc().Sys.Print('spacing s_a of beta_a, quantiles 0 .05 .5 .75 .95 1:',
                         np.quantile(grid.spacing, [0, 0.05, 0.5, 0.75, 0.95, 1]))
t = time.time()
r = pf.solve(sc, grid, 0.01, options={'pf_start': 'sharp', 'pf_stage1_rtol': 1e-5}, checks=True)
pf.api.petsc().Sys.Print(f, gamma, q, order, grid.n_nodes, r.energy, r.attrs['level_set_energy'],
                         r.attrs['nu_area'], r.attrs['nu_volume'], time.time() - t,
                         'max |phi_a|', np.abs(r.phi).max())
