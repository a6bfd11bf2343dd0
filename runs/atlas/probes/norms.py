"""norms.py BRANCH.h5: the largest and the RMS nodal value of a branch's first point and,
between its first six points, the RMS change of the nodal values (the continuation's
arclength norm) against the RMS change of phi_h on a raster of the box: how much of a step
the nodal values take that the field does not show."""
import sys

import numpy as np

from pfmembrane.analysis import levelset
from pfmembrane.result import read_branch

shapes, b = read_branch(sys.argv[1])
box = b['box']
r, z = np.meshgrid(np.linspace(0, box[0], 120), np.linspace(0, box[1], 210))
points = np.column_stack([r.ravel(), z.ravel()])
beta = shapes[0].locality()
fields = [levelset.PhaseField(s.checkpoint(), beta)(points) for s in shapes[:6]]
phi = shapes[0].phi
print(f"{sys.argv[1]}: {len(phi)} nodes, basis {shapes[0].basis}; nodal values: largest "
      f"{np.abs(phi).max():.4g}, RMS {np.sqrt(np.mean(phi ** 2)):.3g}")
print("| v | v' | nodal RMS change | phi_h RMS change | ratio |\n|---|---|---|---|---|")
for k in range(1, len(fields)):
    a, c = shapes[k - 1], shapes[k]
    dx = np.sqrt(np.mean((c.phi - a.phi) ** 2))
    df = np.sqrt(np.mean((fields[k] - fields[k - 1]) ** 2))
    print(f"| {a.attrs['reduced_volume']:.4f} | {c.attrs['reduced_volume']:.4f} | {dx:.3e} | "
          f"{df:.3e} | {dx / df:.2f} |")
