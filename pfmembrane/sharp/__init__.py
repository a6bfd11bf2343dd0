"""The sharp-interface solver: axisymmetric Canham-Helfrich shapes of the same
scenes, a second solver of the same model (`solver`), the reference every
phase field is checked against. Pure numpy/scipy.

    from pfmembrane import sharp
    shape = sharp.solve(0.8, 'oblate')      # reduced volume, family
    shape.energy, shape.tension, shape.pressure
"""
from pfmembrane.sharp.solver import (BRANCHES, SharpShape, energy_reference, pear_bifurcation,
                                     pear_mode, shape_energy, solve)

__all__ = ['BRANCHES', 'SharpShape', 'energy_reference', 'pear_bifurcation', 'pear_mode',
           'shape_energy', 'solve']
