"""band.py F GAMMA W: adapted.py's solve at v 0.62 on nodes relocated for
rho = 1 + F max_{|y - x| < W} |grad phi_h|(y) (`pf.adapt`'s band): the density flat across
the interfaces' band, so the nodes are graded only where phi_h is near +-1."""
import sys, time
import numpy as np
import pfmembrane as pf
from pfmembrane.result import read_branch
pf.api.petsc(sys.argv[:1])
f, gamma, w = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
along, coarse = read_branch('runs/atlas/adapted_stomatocyte/coarse/branches/stomatocyte_c0.h5')
nodes = pf.adapt(along[0], f, along=along[1:], band=w, gamma=gamma).nodes
sc = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=coarse['box'], branch='stomatocyte', symmetric=False)
grid = pf.Grid(sc, nodes, gamma=gamma)
pf.api.petsc().Sys.Print('spacing s_a of beta_a, quantiles 0 .05 .5 .75 .95 1:',
                         np.quantile(grid.spacing, [0, 0.05, 0.5, 0.75, 0.95, 1]))
t = time.time()
r = pf.solve(sc, grid, 0.01, options={'pf_start': 'sharp', 'pf_stage1_rtol': 1e-5}, checks=True)
pf.api.petsc().Sys.Print(f, gamma, w, grid.n_nodes, r.energy, r.attrs['level_set_energy'],
                         r.attrs['nu_area'], r.attrs['nu_volume'], time.time() - t,
                         'max |phi_a|', np.abs(r.phi).max())
