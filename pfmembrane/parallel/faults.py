"""Interruption by SIGTERM or SIGINT, or by a deadline, without losing the run.

The signal handler only records the signal. The solver polls the record
collectively once per iteration (`poll`, from `Solver.evaluate`), so every
rank raises `Interrupted` at the same iteration, even when only one rank
received the signal; the application then checkpoints its last iterate (in
stage 2, which hands its iterate back only when it ends: the stage-1 result)
with ``converged = 0`` and exits with status 128 + the signal number (143 for
SIGTERM, 130 for SIGINT), the shell's convention for a signalled process.

A second signal ends the process at once with the signal's default action;
the checkpoint file is replaced atomically, so the last complete one stays.

Open MPI's `mpiexec`, given SIGTERM or SIGINT, sends SIGTERM to every rank
after ``odls_base_sigkill_timeout`` seconds (default 1) and SIGKILL as long
again later: ``OMPI_MCA_odls_base_sigkill_timeout=60`` gives the ranks a
minute to checkpoint. Batch systems (Slurm) signal the ranks themselves.

A time budget stops a solve the same way: inside `deadline(at)` the poll
raises `OutOfTime` on every rank at the first iteration after any rank's
clock passed `at`, so a budget holds within one iteration, not one solve.
"""
import contextlib
import math
import signal
import time

from mpi4py import MPI

SIGNALS = (signal.SIGTERM, signal.SIGINT)

_received = 0  # number of the first signal received, 0 while none
_deadline = math.inf  # time.perf_counter() at which solves stop (`deadline`)


class Interrupted(Exception):
    """A run stopped by a signal, raised on every rank at the same poll.

    Attributes
    ----------
    signum : int
        The signal (the largest number when ranks received different ones).
    status : int
        Exit status of the process: 128 + `signum`.
    """

    def __init__(self, signum):
        self.signum = signum
        self.status = 128 + signum
        super().__init__(f"interrupted by {signal.Signals(signum).name}")


class OutOfTime(Exception):
    """A solve stopped at its deadline, raised on every rank at the same poll.

    Attributes
    ----------
    status : int
        124, the exit status of timeout(1) for a command it stopped.
    """

    status = 124

    def __init__(self):
        super().__init__("stopped at the time budget")


def _record(signum, frame):
    global _received
    if _received:
        signal.signal(signum, signal.SIG_DFL)
        signal.raise_signal(signum)
    _received = signum


def install():
    """Record SIGTERM and SIGINT instead of dying. Not collective."""
    for signum in SIGNALS:
        signal.signal(signum, _record)
        # Restart interrupted system calls in MPI, HDF5 and MUMPS rather than
        # have them fail with EINTR: the record is all that matters.
        signal.siginterrupt(signum, False)


@contextlib.contextmanager
def deadline(at):
    """Within the block, solves stop with `OutOfTime` once time.perf_counter()
    passes `at` (an earlier deadline in force stays). Not collective."""
    global _deadline
    saved = _deadline
    _deadline = min(saved, at)
    try:
        yield
    finally:
        _deadline = saved


def poll(comm):
    """Raise `Interrupted` on every rank if any rank received a signal, else
    `OutOfTime` if any rank's clock passed the deadline.

    Collective: one allreduce of a pair, (signal, late) ordered so a signal wins.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm
    """
    signum, late = comm.allreduce((_received, time.perf_counter() > _deadline), op=MPI.MAX)
    if signum:
        raise Interrupted(signum)
    if late:
        raise OutOfTime()
