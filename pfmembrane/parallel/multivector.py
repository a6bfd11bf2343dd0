"""The grid's operators applied to every harmonic at once by PETSc's MAIJ kernels.

A field with nh harmonics is a rank-local array of nh interleaved columns (node
a, harmonic j at nh a + j), and B applied to each column is the product of
MATMAIJ: the operator B (quadrature points x local nodes) acting on dof = nh
interleaved components, with kernels unrolled in the components, where scipy's
multi-vector product runs at about the speed of nh single ones. It stands in for
`kernels.harmonics.SparseProducts` in the Hessian actions of the Krylov solver,
which spend most of their time in these products. petsc4py wraps neither
MatCreateMAIJ nor a Mat from its handle, so the MAIJ matrices are handles on the
PETSc library (`petsc.libpetsc`), destroyed by `destroy`. Not collective: every
matrix lives on PETSC_COMM_SELF.
"""
import ctypes

import numpy as np

from pfmembrane.kernels.harmonics import SparseProducts
from pfmembrane.parallel.petsc import c_int, libpetsc, start


class MAIJProducts:
    """`SparseProducts` of the operators `ops` for nh harmonics, by MATMAIJ
    products: B X for each operator, and sum B^T Y through the transposes
    (stored as AIJ: MAIJ's own transposed product scatters and is slower).
    The forward AIJ matrices share the operators' arrays."""

    def __init__(self, ops, nh):
        PETSc = start()
        self.nh, self.lib = nh, libpetsc()
        self._aij, self._maij = [], {}
        for name in SparseProducts.NAMES:
            B = getattr(ops, name)
            for key, M in ((name, B), (name + 'T', B.T.tocsr())):
                A = PETSc.Mat().createAIJWithArrays(
                    M.shape, (M.indptr.astype(PETSc.IntType, copy=False),
                              M.indices.astype(PETSc.IntType, copy=False), M.data),
                    comm=PETSc.COMM_SELF)
                handle = ctypes.c_void_p()
                self._call('MatCreateMAIJ', ctypes.c_void_p(A.handle), c_int()(nh),
                           ctypes.byref(handle))
                self._aij.append(A)  # the MAIJ holds a reference; the arrays live here
                self._maij[key] = (handle, M.shape)

    def _call(self, name, *args):
        code = getattr(self.lib, name)(*args)
        if code:
            raise start().Error(code)

    def _vec(self, array):
        PETSc = start()
        return PETSc.Vec().createWithArray(array.reshape(-1), comm=PETSc.COMM_SELF)

    def forward(self, X):
        X = np.ascontiguousarray(X, dtype=float)
        x = self._vec(X)
        out = []
        for name in SparseProducts.NAMES:
            handle, shape = self._maij[name]
            Y = np.empty((shape[0], self.nh))
            y = self._vec(Y)
            self._call('MatMult', handle, ctypes.c_void_p(x.handle), ctypes.c_void_p(y.handle))
            y.destroy()
            out.append(Y)
        x.destroy()
        return tuple(out)

    def adjoint(self, Y):
        out = None
        for name, given in Y.items():
            handle, shape = self._maij[name + 'T']
            y = self._vec(np.ascontiguousarray(given, dtype=float))
            if out is None:
                out = np.empty((shape[0], self.nh))
                acc = self._vec(out)
                self._call('MatMult', handle, ctypes.c_void_p(y.handle),
                           ctypes.c_void_p(acc.handle))
            else:
                self._call('MatMultAdd', handle, ctypes.c_void_p(y.handle),
                           ctypes.c_void_p(acc.handle), ctypes.c_void_p(acc.handle))
            y.destroy()
        acc.destroy()
        return out

    def destroy(self):
        """Free the MAIJ matrices (and with them the AIJ ones)."""
        for handle, _ in self._maij.values():
            self._call('MatDestroy', ctypes.byref(handle))
        self._maij.clear()
        for A in self._aij:
            A.destroy()
        self._aij.clear()
