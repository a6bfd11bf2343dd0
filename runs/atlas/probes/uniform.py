"""uniform.py EPS SPACING GAMMA ORDER: the stomatocyte at v 0.62, c0 0 on the uniform grid
of `paper_spacing(SPACING)` (84000: 10,080 nodes); ORDER 2 needs quadratic.patch applied and
PFMEMBRANE_MAXENT_ORDER=2."""
import os, sys, time
import pfmembrane as pf
from pfmembrane.paper import paper_spacing
pf.api.petsc(sys.argv[:1])
eps, spacing, gamma, order = float(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
if order != int(os.environ.get('PFMEMBRANE_MAXENT_ORDER', '1')):
    sys.exit(f'ORDER {order}: apply quadratic.patch and set PFMEMBRANE_MAXENT_ORDER={order}')
sc = pf.Scene(reduced_volume=0.62, c0=0.0, radius=0.4, box=(0.45, 0.8), branch='stomatocyte', symmetric=False)
g = pf.Grid.uniform(sc, nodes=paper_spacing(spacing, sc.box), gamma=gamma)
t = time.time()
r = pf.solve(sc, g, eps, options={'pf_start': 'sharp', 'pf_force': True}, checks=True)
pf.api.petsc().Sys.Print(order, gamma, g.n_nodes, r.energy, r.attrs['level_set_energy'],
                         r.attrs['nu_area'], r.attrs['nu_volume'], time.time() - t)
