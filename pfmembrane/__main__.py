"""python -m pfmembrane [-options_file FILE] [-pf_* ...] [PETSc options]

PETSc is initialized with sys.argv before anything imports it, and every
failure ends every rank, with one line on stderr (from rank 0, or from the
failing rank when only one fails):

- invalid input (an options file PETSc cannot read, an unknown or unused
  option, a bad value, an unreadable restart checkpoint, an output path that
  cannot be written): status 2;
- a solve that did not converge: status 1, its checkpoint marked
  ``converged = 0``;
- SIGTERM or SIGINT: the current iterate checkpointed (``converged = 0``),
  status 128 + the signal number (see `pfmembrane.parallel.faults`);
- a PETSc error: status 3;
- an unexpected exception on one rank aborts COMM_WORLD (status 4), so no
  rank hangs in a collective waiting for it.

Options given at start-up and still unused when a run has converged are
refused (status 2) after its checkpoint is written; `-options_left` keeps
PETSc's behaviour instead (a warning when PETSc finalizes).
"""
import os
import sys
import tempfile

import petsc4py


def one_line(text):
    """`text` as one printable line."""
    return ' '.join(''.join(c if c.isprintable() else ' ' for c in str(text)).split())


def petsc_message(stack):
    """The message of a PETSc error stack: the lines after its header, up to
    the pointer to the FAQ, without the unused-options warning."""
    lines, inside = [], False
    for line in stack.splitlines():
        _, found, text = line.partition('PETSC ERROR: ')
        if not found:
            continue
        if text.startswith('---'):
            inside = True
        elif text.startswith('See ') or text.startswith('Petsc Release'):
            break
        elif inside and not text.startswith(('WARNING!', 'Option left:')):
            lines.append(text)
    return ': '.join(lines)


def initialize():
    """petsc4py.init(sys.argv), or one line on stderr and status 2.

    PETSc reads -options_file inside PetscInitialize and reports a missing or
    malformed file there, with an error stack on stderr; the stack is captured
    from file descriptor 2 and reduced to its message. Rank 0 reads the files
    and the others wait for it inside PetscInitialize, where no collective can
    reach them: a failing rank aborts COMM_WORLD instead of exiting.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    failure = None
    with tempfile.TemporaryFile() as capture:
        os.dup2(capture.fileno(), 2)
        try:
            petsc4py.init(sys.argv)
            from petsc4py import PETSc  # noqa: F401 - PetscInitialize runs here at the latest
        except Exception as e:  # noqa: BLE001 - whatever stops PETSc from starting
            failure = e
        finally:
            sys.stderr.flush()
            os.dup2(saved, 2)
            os.close(saved)
        capture.seek(0)
        stack = capture.read().decode(errors='replace')
    if failure is None:
        sys.stderr.write(stack)
        return
    from mpi4py import MPI  # already started by PetscInitialize: no communication here
    if MPI.COMM_WORLD.Get_rank() == 0:
        message = one_line(petsc_message(stack) or failure)
        sys.stderr.write(f"pfmembrane: error: cannot start PETSc: {message}\n")
        sys.stderr.flush()
    MPI.COMM_WORLD.Abort(2)


initialize()

from petsc4py import PETSc  # noqa: E402

from pfmembrane.parallel import faults, petsc  # noqa: E402
from pfmembrane.io import options  # noqa: E402
from pfmembrane.io.checkpoint import CheckpointError  # noqa: E402


def precheck(opts, comm):
    """Refuse bad options and an unwritable output path before importing the
    numerical code, which alone takes about a second per rank. Collective."""
    if not opts.hasName('help'):
        from pfmembrane.starts import check_run
        p = options.read(opts)
        check_run(p)
        options.check_output(p.output or options.default_output(p), comm.tompi4py())


def main():
    comm = PETSc.COMM_WORLD
    opts = PETSc.Options()
    given = list(opts.getAll())
    faults.install()
    try:
        precheck(opts, comm)
        from pfmembrane.cli.app import run
        status = run(comm)
        if status == 0:
            options.check_unused(opts, comm.tompi4py(), given, petsc.options_left())
    except (options.UsageError, CheckpointError) as e:
        # Every rank reaches the same verdict from the same input.
        if comm.getRank() == 0:
            sys.stderr.write(f"pfmembrane: error: {one_line(e)}\n")
        status = 2
    except PETSc.Error as e:
        if comm.getRank() == 0:
            sys.stderr.write(f"pfmembrane: PETSc error {e.ierr}: see the message above\n")
        status = 3
    except BaseException as e:  # noqa: BLE001 - one rank's failure must end all ranks
        sys.stderr.write(f"pfmembrane: rank {comm.getRank()}: {type(e).__name__}: {one_line(e)}\n")
        sys.stderr.flush()
        comm.tompi4py().Abort(4)
    sys.exit(status)


main()
