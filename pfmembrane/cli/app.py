"""The application: the global options database -> `runner.execute` -> summary.

The solve and the mode analysis run as problems of their own, each under an
options prefix of its own (`parallel.problem.Problem`); the command line's
solver options (`-stage1_*`, `-stage2_*`, `-modes_*` and the solver's `-pf_`
settings) are read here and handed to them, and an option handed on that no
solver used is refused as any unused option is.
"""
import sys
from dataclasses import fields

from petsc4py import PETSc

from pfmembrane.cli import runner
from pfmembrane.io import options

SOLVE = ('stage1_', 'stage2_')
MODES = ('modes_',)


def handed(opts, starts):
    """The options of the global database whose names start with one of
    `starts`, read (so PETSc counts them used)."""
    return {name: opts.getString(name) for name in sorted(opts.getAll())
            if name.lower().startswith(starts)}


def run(comm):
    """Collective. Returns the process exit status."""
    opts = PETSc.Options()
    if opts.hasName('help'):
        PETSc.Sys.Print(options.help_text())
        return 0
    p = options.read(opts)
    solve = {**handed(opts, SOLVE),
             **{'pf_' + f.name: getattr(p, f.name) for f in fields(options.Settings)}}
    modes = handed(opts, MODES) if p.modes >= 0 else None
    res, output = runner.execute(p, comm, PETSc.Sys.Print, solve, modes_options=modes)
    runner.summary(res, output, PETSc.Sys.Print)
    if res.unused_options and not opts.hasName('options_left'):
        raise options.UsageError(
            f"option{'s' if len(res.unused_options) > 1 else ''} "
            f"{', '.join('-' + n for n in res.unused_options)} never used (misspelt, or for a "
            "solver this run does not create); -options_left reports them without failing")
    if not res.converged and comm.getRank() == 0:
        sys.stderr.write(f"pfmembrane: {res.message} (checkpoint {output} marked converged = 0)\n")
    return res.status
