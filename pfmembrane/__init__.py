"""pfmembrane: equilibrium vesicle shapes with the Du-Liu-Wang phase-field
Helfrich model on local max-ent approximants, solved with PETSc.

    import pfmembrane as pf
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid = pf.Grid.uniform(scene, nodes=6124)
    result = pf.solve(scene, grid, eps=0.04)

The names below are gathered in `pfmembrane.api` (which says what each is)
and imported on first use from their own modules, so that `python -m
pfmembrane` starts PETSc before any numerical code loads and that reading a
result (`read`, `Result`) or describing a scene (`Scene`) needs no PETSc.
`petsc()` returns petsc4py's PETSc, started with the script's arguments.
"""
import importlib

_HOME = {'Scene': 'scene', 'Result': 'result', 'read': 'result', 'Grid': 'grid',
         'adapt': 'grid', 'solve': 'equilibrium', 'stability': 'equilibrium',
         'continuation': 'branching', 'tangent': 'branching', 'predict': 'branching',
         'along': 'branching', 'accurate': 'accuracy', 'petsc': 'api'}
__all__ = list(_HOME)


def __getattr__(name):
    if name in _HOME:
        return getattr(importlib.import_module('pfmembrane.' + _HOME[name]), name)
    if name == 'api':
        return importlib.import_module('pfmembrane.api')
    raise AttributeError(f"module 'pfmembrane' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
