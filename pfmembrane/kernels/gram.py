"""Weighted Gram matrices of basis rows, batched per background triangle.

Every Hessian of the functionals has the form

    H = sum_q sum_k s_k(q) g_k(q) g_k(q)^T,   g_k(q) = sum_j c_kj(q) B_j[q, :],

with B_j the operators (value, Laplacian, gradient) at the quadrature points.
A sparse triple product B^T diag(s) B does this one point at a time through a
hash accumulator. Here the points of one triangle share one support (the
union of theirs), so each triangle is one small dense product G^T diag(s) G
(a batched BLAS call), and a precomputed slot map adds its upper triangle
into the data array of the local Hessian's exact pattern. Pairs of nodes
that share no quadrature point (possible within the union) map to a discard
slot, so the pattern is exactly that of the point-wise product.
"""
import numpy as np
import scipy.sparse as sp

CHUNK = 256  # triangles per batched product: bounds the dense temporaries


class Gram:
    """Batched Gram products on the pattern of sum_j B_j^T B_j.

    Not collective. `operators` maps names to CSR matrices (points x local
    unknowns) with one sparsity structure; the points are grouped by triangle,
    `per_cell` consecutive points each. `dense` names the operators whose
    per-triangle blocks are kept for repeated products; others are blocked
    on demand.
    """

    def __init__(self, operators, per_cell, pattern, dense=('B0', 'BL')):
        self.operators, self.per_cell = operators, per_cell
        ref = next(iter(operators.values()))
        npts, n = ref.shape
        ncell = npts // per_cell
        rows = np.repeat(np.arange(npts), np.diff(ref.indptr))
        cell, point = np.divmod(rows, per_cell)
        # Support of each triangle: the sorted union of its points' columns.
        keys = np.unique(cell * n + ref.indices)
        cell_of, col_of = np.divmod(keys, n)
        size = np.bincount(cell_of, minlength=ncell)
        first = np.concatenate([[0], np.cumsum(size)])
        pos = np.searchsorted(keys, cell * n + ref.indices) - first[cell]
        self.pattern, self.upper, self._full_from_upper = self._patterns(pattern)
        U = self.upper
        # Slot numbers + 1 (0: no entry) by element look-up in a CSR of the upper
        # pattern: a row-wise search, 3x faster than one searchsorted over all keys.
        lookup = sp.csr_matrix((np.arange(1, U.nnz + 1, dtype=float), U.indices, U.indptr),
                               shape=U.shape)
        # Chunks of triangles of similar support size, each padded to its largest.
        order = np.argsort(size, kind='stable')
        chunk_of = np.empty(ncell, dtype=np.int64)
        local = np.empty(ncell, dtype=np.int64)
        chunk_of[order] = np.arange(ncell) // CHUNK
        local[order] = np.arange(ncell) % CHUNK
        by_chunk = np.argsort(chunk_of[cell], kind='stable')
        bounds = np.searchsorted(chunk_of[cell][by_chunk], np.arange(-(-ncell // CHUNK) + 1))
        self.chunks = []
        for i, start in enumerate(range(0, ncell, CHUNK)):
            cells = order[start:start + CHUNK]
            m = int(size[cells].max())
            support = np.full((len(cells), m), -1, dtype=np.int64)
            filled = np.arange(m)[None, :] < size[cells][:, None]
            support[filled] = col_of[np.concatenate([np.arange(first[c], first[c + 1])
                                                     for c in cells])]
            iu, ju = np.triu_indices(m)
            a, b = support[:, iu], support[:, ju]
            padded = (a < 0) | (b < 0)
            found = lookup[np.where(padded, 0, a).ravel(), np.where(padded, 0, b).ravel()]
            slot = np.asarray(found).astype(np.int64).reshape(a.shape) - 1
            e = by_chunk[bounds[i]:bounds[i + 1]]  # operator entries of these triangles
            self.chunks.append(dict(
                cells=cells, m=m, flat=iu * m + ju,
                slots=np.where(padded | (slot < 0), U.nnz, slot).astype(np.int32),
                entries=e, at=(local[cell[e]] * per_cell + point[e]) * m + pos[e]))
        self._blocks = {name: self.block(name) for name in dense}

    @staticmethod
    def _patterns(pattern):
        """The full pattern, its upper triangle and the map full entry -> upper entry."""
        P = sp.csr_matrix(pattern)
        P.sort_indices()
        n = P.shape[0]
        row = np.repeat(np.arange(n), np.diff(P.indptr))
        U = sp.triu(P).tocsr()
        U.sort_indices()
        ukeys = np.repeat(np.arange(n), np.diff(U.indptr)) * n + U.indices
        lo, hi = np.minimum(row, P.indices), np.maximum(row, P.indices)
        return P, U, np.searchsorted(ukeys, lo * n + hi)

    def block(self, name):
        """Dense per-chunk blocks (cells x per_cell x m) of one operator."""
        data = self.operators[name].data
        out = []
        for c in self.chunks:
            blk = np.zeros(len(c['cells']) * self.per_cell * c['m'])
            blk[c['at']] = data[c['entries']]
            out.append(blk.reshape(len(c['cells']), self.per_cell, c['m']))
        return out

    def blocks(self, names):
        """Dense per-chunk blocks of the operators `names`: those kept (`dense`)
        and the others built for a caller that keeps them as long as it needs."""
        return {name: self._blocks[name] if name in self._blocks else self.block(name)
                for name in names}

    def upper_data(self, terms, blocks=None):
        """Data of the upper-triangular pattern of sum_q sum_k s_k g_k g_k^T.

        `terms` is a list of (coefficients, s): coefficients maps operator
        names to per-point arrays or scalars (c_kj), s is per point.
        """
        blocks = blocks or self._blocks
        data = np.zeros(len(self.upper.data) + 1)
        g = self.per_cell
        for i, c in enumerate(self.chunks):
            idx = (c['cells'][:, None] * g + np.arange(g)).ravel()
            rows, weights = [], []
            for coefficients, s in terms:
                row = 0.0
                for name, coef in coefficients.items():
                    cq = coef[idx].reshape(-1, g, 1) if np.ndim(coef) else coef
                    row = row + cq * blocks[name][i]
                rows.append(row)
                weights.append(s[idx].reshape(-1, g, 1))
            G = np.concatenate(rows, axis=1)
            S = np.concatenate(weights, axis=1)
            H = np.matmul((G * S).transpose(0, 2, 1), G)
            # np.take along an axis gathers 4-5x faster than fancy indexing
            upper = np.take(H.reshape(len(idx) // g, -1), c['flat'], axis=1)
            data += np.bincount(c['slots'].ravel(), weights=upper.ravel(), minlength=len(data))
        return data[:-1]

    def full(self, upper):
        """The symmetric CSR matrix on the full pattern from upper-pattern data."""
        P = self.pattern
        return sp.csr_matrix((upper[self._full_from_upper], P.indices, P.indptr), shape=P.shape)
