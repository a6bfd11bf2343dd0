"""The application: the global options database -> `run.execute` -> summary."""
import sys

from petsc4py import PETSc

from pfmembrane import run as runs
from pfmembrane.io import options


def run(comm):
    """Collective. Returns the process exit status."""
    opts = PETSc.Options()
    if opts.hasName('help'):
        PETSc.Sys.Print(options.help_text())
        return 0
    p = options.read(opts)
    res, output = runs.execute(p, comm, PETSc.Sys.Print)
    runs.summary(res, output, PETSc.Sys.Print)
    if not res.converged and comm.getRank() == 0:
        sys.stderr.write(f"pfmembrane: {res.message} (checkpoint {output} marked converged = 0)\n")
    return res.status
