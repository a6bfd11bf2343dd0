"""The application: the global options database -> `runner.execute` -> summary.

The solve and the mode analysis run as problems of their own, each under an
options prefix of its own (`parallel.problem.Problem`); the command line's
solver options (`-stage1_*`, `-stage2_*`, `-modes_*`) and the solver's `-pf_`
settings are handed to them. An option handed on counts as used where its
copy was used; the others stay unused, for `-options_left` to list and for
the unused-option check to refuse, as any unused option.
"""
import sys
import warnings
from dataclasses import fields

from petsc4py import PETSc

from pfmembrane.cli import runner
from pfmembrane.io import options

SOLVE = ('stage1_', 'stage2_')
MODES = ('modes_',)


def handed(opts, starts):
    """The options of the global database whose names start with one of
    `starts` (not yet counted used)."""
    return {name: value for name, value in sorted(opts.getAll().items())
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
    with warnings.catch_warnings():
        # unused options are the unused-option check's to report (`__main__`)
        warnings.filterwarnings('ignore', 'solve options never used')
        warnings.filterwarnings('ignore', 'stability options never used')
        # a saddle is the summary's to report (`runner.summary`)
        warnings.filterwarnings('ignore', 'the solve returned to the axisymmetric state')
        if p.tol:  # accuracy on demand: a sequence of solves (pfmembrane.accuracy)
            from pfmembrane import accuracy
            res, output = accuracy.execute(p, comm, PETSc.Sys.Print, solve)
        else:
            res, output = runner.execute(p, comm, PETSc.Sys.Print, solve, modes_options=modes)
    runner.summary(res, output, PETSc.Sys.Print)
    given, unused = opts.getAll(), {n.lower() for n in res.unused_options}
    for name in {**solve, **(modes or {})}:
        if name in given and name.lower() not in unused:
            opts.getString(name)  # its copy was used: so is it
    if not res.converged and comm.getRank() == 0:
        sys.stderr.write(f"pfmembrane: {res.message} (checkpoint {output} marked converged = 0)\n")
    return res.status
