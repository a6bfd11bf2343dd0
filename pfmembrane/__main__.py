"""python -m pfmembrane [-options_file FILE] [-pf_* ...] [PETSc options]

PETSc is initialized with sys.argv before anything imports it, and any error
ends every rank: invalid input prints one line and exits with status 2; an
unexpected exception on one rank aborts COMM_WORLD so no rank hangs.
"""
import sys

import petsc4py

petsc4py.init(sys.argv)

from petsc4py import PETSc  # noqa: E402

from .app import run  # noqa: E402
from .checkpoint import CheckpointError  # noqa: E402
from .options import UsageError  # noqa: E402


def main():
    comm = PETSc.COMM_WORLD
    try:
        status = run(comm)
    except (UsageError, CheckpointError) as e:
        # Every rank reaches the same verdict from the same input.
        if comm.getRank() == 0:
            sys.stderr.write(f"pfmembrane: error: {e}\n")
        status = 2
    except PETSc.Error as e:
        if comm.getRank() == 0:
            sys.stderr.write(f"pfmembrane: PETSc error {e.ierr}: see the message above\n")
        status = 3
    except BaseException as e:  # noqa: BLE001 - one rank's failure must end all ranks
        sys.stderr.write(f"pfmembrane: rank {comm.getRank()}: {type(e).__name__}: {e}\n")
        sys.stderr.flush()
        comm.tompi4py().Abort(4)
    sys.exit(status)


main()
