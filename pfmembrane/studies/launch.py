"""Child runs of the application, for the drivers (tables, sequences, branches,
benchmarks, the stability study): the one place that builds an mpiexec line
and the environment it runs in."""
import os
import subprocess
import sys


def command(nprocs, *args, module='pfmembrane'):
    """`mpiexec -n NPROCS python -m MODULE ARGS...` with this interpreter."""
    return ['mpiexec', '-n', str(nprocs), sys.executable, '-m', module, *args]


def environment():
    """Python's copy of the environment. Once MPI is initialised in this process
    (under pytest, or after importing PETSc for a measurement), it has added
    variables to the C environment that make a child mpiexec fail at once."""
    return dict(os.environ)


def run(cmd, **kwargs):
    """subprocess.run of an mpiexec line in `environment()`."""
    return subprocess.run(cmd, env=environment(), **kwargs)
