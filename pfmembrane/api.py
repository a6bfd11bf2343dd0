"""The public API, gathered in one module: a scene, a grid built once, solves
on it, continuation, stability, and their results.

Grids, solves and adaptation are collective on the grid's communicator
(PETSc's COMM_WORLD unless given). PETSc starts on first use: with the
script's command-line arguments, so `-log_view` or `-info` reach it, except
in an interactive session or a notebook, whose arguments are not PETSc's.
Reading a result, and `Scene`, need no PETSc at all. A call prints nothing
unless asked (`pf_monitor`, `pf_summary` among its options).

Where each name lives:

- `Scene` (`scene`): the vesicle; `Result`, `read` (`result`): a solved state;
- `Grid`, `adapt` (`grid`): nodes and their basis, built once; CVT-adapted grids;
- `solve`, `stability` (`equilibrium`): an equilibrium and its azimuthal spectra (with
  harmonics: its index within them);
- `continuation`, `tangent`, `predict`, `along` (`branching`): branches;
- `accurate` (`accuracy`): the sharp-limit energy to a tolerance, with an error bar.
"""
from pfmembrane.accuracy import accurate
from pfmembrane.branching import along, continuation, predict, tangent
from pfmembrane.equilibrium import solve, stability
from pfmembrane.grid import Grid, adapt
from pfmembrane.parallel.petsc import start as petsc
from pfmembrane.result import Result, read
from pfmembrane.scene import Scene

__all__ = ['Scene', 'Result', 'read', 'Grid', 'adapt', 'solve', 'stability', 'continuation',
           'tangent', 'predict', 'along', 'accurate', 'petsc']
