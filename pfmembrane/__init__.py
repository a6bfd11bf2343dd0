"""pfmembrane: equilibrium vesicle shapes with the Du-Liu-Wang phase-field
Helfrich model on local max-ent approximants, solved with PETSc.

    import pfmembrane as pf
    scene = pf.Scene(reduced_volume=0.8, branch='oblate')
    grid = pf.Grid.uniform(scene, nodes=6124)
    result = pf.solve(scene, grid, eps=0.04)

The names below come from `pfmembrane.api` (which says where each lives),
imported on first use so that `python -m pfmembrane` starts PETSc before any
numerical code loads. `petsc()` returns petsc4py's PETSc, started with the
script's arguments.
"""
__all__ = ['Scene', 'Grid', 'Result', 'solve', 'adapt', 'read', 'predict', 'tangent', 'along',
           'continuation', 'stability', 'petsc']


def __getattr__(name):
    if name in __all__ or name == 'api':
        import importlib
        api = importlib.import_module('pfmembrane.api')
        return api if name == 'api' else getattr(api, name)
    raise AttributeError(f"module 'pfmembrane' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + __all__)
