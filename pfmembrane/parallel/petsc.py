"""PETSc for the rest of the package: start-up, the library handle, the MUMPS
defaults, and the one writer of the options database (`Options`).

PETSc's options database is global state. Every key this package puts there
goes through an `Options` scope: under a non-empty prefix of its own, each
value it replaced restored and each key it added removed when it closes.
"""
import ctypes
import functools
import sys

import numpy as np

# MUMPS LDL^T for the symmetric indefinite (bordered) matrices: QAMD ordering
# (Debian's MUMPS has no METIS, and PORD was 4x slower), inertia that is right
# in parallel (no ScaLAPACK root), null-pivot detection instead of failure
# (PETSc's MatGetInertia needs it to count zero pivots).
MUMPS_LDLT = {'mat_mumps_icntl_7': '6', 'mat_mumps_icntl_13': '1', 'mat_mumps_icntl_24': '1'}


def start(args=None):
    """petsc4py's PETSc, started on first use with `args` (by default the
    command line, or nothing in an interactive session)."""
    if 'petsc4py.PETSc' not in sys.modules:
        import petsc4py
        if args is None:
            interactive = hasattr(sys, 'ps1') or 'ipykernel' in sys.modules
            args = sys.argv[:1] if interactive else sys.argv
        petsc4py.init(args)
    from petsc4py import PETSc
    PETSc.Log.begin()  # event times feed each result's time split
    return PETSc


def comm(c=None):
    """A PETSc communicator from None (COMM_WORLD), an mpi4py or a PETSc one."""
    PETSc = start()
    if c is None:
        return PETSc.COMM_WORLD
    return c if isinstance(c, PETSc.Comm) else PETSc.Comm(c)


@functools.cache
def libpetsc():
    """The PETSc library petsc4py's extension links, for the calls petsc4py
    does not wrap (PetscOptionsLeftGet, the inertia inside a PCREDUNDANT)."""
    return ctypes.CDLL(start().__file__)


def c_int():
    """The ctypes type of PetscInt."""
    return ctypes.c_int64 if np.dtype(start().IntType).itemsize == 8 else ctypes.c_int32


def options_left():
    """Names (lower case, without the dash) of the options nothing looked up."""
    lib = libpetsc()
    pint = c_int()
    strings = ctypes.POINTER(ctypes.c_char_p)
    args = [ctypes.c_void_p, ctypes.POINTER(pint), ctypes.POINTER(strings),
            ctypes.POINTER(strings)]
    lib.PetscOptionsLeftGet.argtypes = lib.PetscOptionsLeftRestore.argtypes = args
    n, names, values = pint(), strings(), strings()
    refs = (None, ctypes.byref(n), ctypes.byref(names), ctypes.byref(values))
    if lib.PetscOptionsLeftGet(*refs):
        raise RuntimeError("PetscOptionsLeftGet failed")
    left = [names[i].decode().lower() for i in range(n.value)]
    lib.PetscOptionsLeftRestore(*refs)
    return left


def text(value):
    """An options-database value of a Python one."""
    if value is None or value is True:
        return 'true' if value else ''
    if value is False:
        return 'false'
    if isinstance(value, (tuple, list)):
        return ','.join(format(v, 'g') if isinstance(v, float) else str(v) for v in value)
    return str(value)


class Options:
    """The options of one problem under its prefix: `given` (names without the
    dash or the prefix) pushed into the database at once, defaults added by
    `default` where the database has none, all of it undone by `close`.

    A value the database held before under the same name is restored, so a
    user's `-PREFIXname` on the command line is overridden only while the
    scope is open. Not collective: every rank holds its own database.
    """

    def __init__(self, prefix, given=None):
        if not prefix:
            raise ValueError("a problem's options need a prefix of their own (got an empty one)")
        self.prefix, self.db = prefix, start().Options()
        self.given = [self.prefix + k.lstrip('-') for k in (given or {})]
        self._saved = {}
        for key, value in (given or {}).items():
            self._set(self.prefix + key.lstrip('-'), text(value))

    def _set(self, full, value):
        if full not in self._saved:
            self._saved[full] = self.db.getString(full) if self.db.hasName(full) else None
        self.db.setValue(full, value)

    def default(self, name, value):
        """`value` for `name` under the prefix unless the database has one."""
        full = self.prefix + name
        if not self.db.hasName(full):
            self._set(full, text(value))

    def mumps(self, stage):
        """The MUMPS LDL^T defaults for the factorization under `stage`."""
        for name, value in MUMPS_LDLT.items():
            self.default(stage + name, value)

    def unused(self, mpi):
        """The given options that no rank looked up (names under the prefix).
        Collective on the mpi4py communicator `mpi`."""
        if not self.given:
            return []
        mine = set(options_left()) & {k.lower() for k in self.given}
        return sorted(set.intersection(*map(set, mpi.allgather(sorted(mine)))))

    def close(self):
        """Restore the database as the scope found it."""
        saved, self._saved = self._saved, {}
        for full, old in saved.items():
            if old is None:
                self.db.delValue(full)
            else:
                self.db.setValue(full, old)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
