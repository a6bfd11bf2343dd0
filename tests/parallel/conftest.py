import sys

import petsc4py

petsc4py.init(sys.argv[:1])
