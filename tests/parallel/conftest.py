import sys

import petsc4py
import pytest

petsc4py.init(sys.argv[:1])


@pytest.fixture
def distributed():
    """Skips a test comparing COMM_WORLD with one rank when COMM_WORLD is one rank."""
    from petsc4py import PETSc
    if PETSc.COMM_WORLD.getSize() == 1:
        pytest.skip('compares against one rank: run under mpiexec -n 2')
