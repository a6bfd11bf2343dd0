"""Phase fields with azimuthal harmonics on the (r, z) grid, on rank-local arrays.

A scene that is not axisymmetric keeps the (r, z) grid and carries a set S of
harmonics in the angle theta about the axis:

    phi_h(r, z, theta) = sum_j r^m_j chi_j(r, z) T_j(theta),

T_j = cos(m_j theta) or sin(m_j theta), chi_j on the solver's even max-ent
basis; psi = r^m chi has the parity (-1)^m in r and vanishes to order m on the
axis, as a smooth 3D field must (`kernels.azimuthal` gives the reasons). A
scene with a dihedral symmetry of order n pays for m = 0, n, 2n, ..., J n;
cosines alone where a mirror plane through the axis holds, sines too where
none does. S = {cos 0} is the axisymmetric solver, term for term.

The derivatives of r^m chi T follow from those of chi (`kernels.azimuthal`):

    d/dr  = (r^m chi_r + m r^(m-1) chi) T,   d/dz = r^m chi_z T,
    (1/r) d/dtheta = r^(m-1) chi T',
    Lap   = (r^m Lap chi + 2 m r^(m-1) chi_r) T   (Lap chi: the axisymmetric one).

The unknowns. A harmonic's coefficient chi_a meets r^m over its basis
function's support: near the axis its whole effect is of order (h/R)^m,
1e-30 for m = 12 a few nodes off the axis, and those rows of H_m vanish to
rounding, so a factorization of the mode Hessians or a Krylov solve on them
breaks down. The unknowns are therefore x_aj = chi_aj rho_a^m_j (`unknown_scale`:
rho_a = sqrt(r_a^2 + h_a^2), the node's radius, its spacing on the axis), each
about the size of psi near its node; every map here takes and returns x
(chi = s x, gradients s grad_chi, Hessians S H S with s = rho^-m).

Integrals in theta. The operators' weights w already integrate 2 pi r, so a 3D
integral is sum_q w_q times the mean over theta. The integrands are
trigonometric polynomials: W holds phi^3 (harmonics up to 3 J n), W^2 and the
gradients' W W' T_j up to 6 J n. The trapezoid rule on N = 6 J + 1 points of
one period 2 pi / n integrates every harmonic below N n exactly, so the
discrete functionals are the exact theta integrals of the (r, z) quadrature.
"""
import numpy as np
import scipy.sparse

from pfmembrane.kernels.azimuthal import OPERATORS, ModeForms
from pfmembrane.kernels.functionals import F_A, F_E, SQRT2


class Harmonics:
    """The set S: `highest` J (m = j `dihedral`, j = 0..J), cosines, and sines
    (m >= 1) with `sines`. The first harmonic is cos 0, the axisymmetric part.
    Not collective."""

    def __init__(self, highest=0, dihedral=1, sines=False):
        if highest < 0 or dihedral < 1:
            raise ValueError(f"harmonics {highest} and dihedral order {dihedral}: "
                             "need harmonics >= 0 and dihedral >= 1")
        self.highest, self.dihedral, self.sines = int(highest), int(dihedral), bool(sines)
        m = dihedral * np.arange(highest + 1)
        self.m = np.concatenate([m, m[1:]]) if sines else m
        self.sine = np.arange(len(self.m)) > highest
        self.n_theta = 6 * self.highest + 1
        self.theta = 2 * np.pi / dihedral * np.arange(self.n_theta) / self.n_theta
        mt = np.outer(self.theta, self.m)
        # T_j(theta_i) and dT_j / dtheta: (n_theta, nh)
        self.T = np.where(self.sine, np.sin(mt), np.cos(mt))
        self.dT = self.m * np.where(self.sine, np.cos(mt), -np.sin(mt))

    def __len__(self):
        return len(self.m)

    def labels(self):
        """'c0', 'c2', 's2', ...: the stored name of each harmonic."""
        return [('s' if s else 'c') + str(m) for m, s in zip(self.m, self.sine)]


class SparseProducts:
    """The four operators of a grid applied to multi-vectors (nlocal x nh or
    nq x nh), by scipy: `forward` X -> (B0 X, Br X, Bz X, BL X), `adjoint`
    {name: Y} -> sum of B^T Y over the names given. The transposes are built
    once as CSR (scipy's CSC products are slower). Not collective; a faster
    implementation of the same two methods may stand in (`HarmonicForms`)."""

    NAMES = ('B0', 'Br', 'Bz', 'BL')

    def __init__(self, ops):
        self.ops = ops
        self._BT = None

    def forward(self, X):
        return tuple(getattr(self.ops, name) @ X for name in self.NAMES)

    def adjoint(self, Y):
        if self._BT is None:
            self._BT = {name: getattr(self.ops, name).T.tocsr() for name in self.NAMES}
        return sum(self._BT[name] @ y for name, y in Y.items())


def unknown_scale(nodes, h, harmonics):
    """s_aj = rho_a^-m_j, rho_a = sqrt(r_a^2 + h_a^2) (nodes x harmonics):
    chi = s x, x the solver's unknowns (module docstring)."""
    rho = np.sqrt(nodes[:, 0] ** 2 + np.asarray(h) ** 2)
    return rho[:, None] ** -harmonics.m[None, :].astype(float)


class HarmonicForms:
    """E, A, V, M of a field with harmonics `harmonics` on one grid's local
    operators: values, gradients and Hessian-vector products; with m = 1
    (dihedral order 1) the gradient of the moment across the axis X, linear
    in the unknowns, that pins the translation along x (`grad_X`).

    Not collective. A field is a local array x of shape (nlocal, nh), ghosts
    included: the unknowns chi / `scale` (`unknown_scale` of the local nodes;
    1 without); the Dirichlet value -1 belongs to the axisymmetric harmonic
    (the operators' offsets b0 ... enter it alone), the others vanish there.
    `products` applies the operators to every harmonic at once
    (`SparseProducts`, the default, or one with its two methods).
    """

    def __init__(self, ops, eps, k, c0, zc, harmonics, gram=None, coupled=False, scale=None,
                 products=None):
        self.ops, self.eps, self.k, self.c0, self.zc = ops, eps, k, c0, zc
        self.scale = np.ones((ops.B0.shape[1], len(harmonics))) if scale is None else scale
        self.coupled = coupled   # `hessian` and `pattern`: the exact coupled Hessian
        self._gram = gram
        self.products = SparseProducts(ops) if products is None else products
        self.h = harmonics
        r, m = ops.r[:, None], harmonics.m[None, :]
        self.R = r ** m                                    # r^m
        self.dR = m * r ** np.maximum(m - 1, 0)            # m r^(m-1)
        self.R1 = r ** (m - 1.0)                           # r^(m-1), times T' (0 at m = 0)
        self.w = ops.w[:, None]
        nh = len(harmonics)
        mean_T = harmonics.T.mean(axis=0)                  # 1 for cos 0, else 0 (exactly)
        self.grad_V = (0.5 * self.scale * (ops.B0.T @ (self.w * self.R * mean_T))).ravel()
        self.grad_M = (self.scale * (ops.B0.T @ (self.w * self.R * mean_T
                                                 * (ops.z - zc)[:, None]))).ravel()
        self.grad_X = None
        if harmonics.dihedral == 1 and harmonics.highest >= 1:
            # X = int x (1 + phi) / 2 with x = r cos(theta): cos 1 alone, mean cos^2 = 1/2
            cos1 = ((harmonics.m == 1) & ~harmonics.sine)[None, :]
            self.grad_X = (0.25 * self.scale * (ops.B0.T @ (self.w * self.R * r * cos1))).ravel()
        self.shape = (ops.B0.shape[1], nh)
        self._interleaved = self._coupled = self._E = self._factors = None

    # -- fields ------------------------------------------------------------------
    def fields(self, x, offsets=True):
        """u, u_r, u_z, (1/r) u_theta, Lap u of the unknowns x at the quadrature
        points x theta points, each (nq, n_theta); without `offsets` (a
        direction) no Dirichlet part."""
        c, cr, cz, cl = self.products.forward(self.scale * np.reshape(x, self.shape))
        T, dT, R, dR = self.h.T.T, self.h.dT.T, self.R, self.dR
        u = (R * c) @ T
        ur = (R * cr + dR * c) @ T
        uz = (R * cz) @ T
        ut = (self.R1 * c) @ dT
        lap = (R * cl + 2 * dR * cr) @ T
        if offsets:
            o = self.ops
            u += o.b0[:, None]
            ur += o.br[:, None]
            uz += o.bz[:, None]
            lap += o.bL[:, None]
        return u, ur, uz, ut, lap

    def _W(self, u, lap):
        eps, s = self.eps, SQRT2 * self.c0
        W = eps * lap + (u / eps + s) * (1.0 - u * u)
        dW = 1.0 / eps - 3.0 * u * u / eps - 2.0 * s * u
        d2W = -6.0 * u / eps - 2.0 * s
        return W, dW, d2W

    # -- transposes: a field's theta-weighted integrals back onto the chi_j -------
    def _project(self, X, derivative=False):
        """mean over theta of X T_j (or X T_j'): (nq, nh)."""
        return X @ (self.h.dT if derivative else self.h.T) / self.h.n_theta

    def _adjoint(self, u=None, r=None, z=None, t=None, lap=None):
        """The transpose of chi -> (psi, psi_r, psi_z, psi_theta / r, Lap psi)
        at the quadrature points against the projections (u, r, z, t, lap)
        (t against T_j'): one product per operator."""
        w, R, dR = self.w, self.R, self.dR
        Y = {}
        for name, pairs in (('B0', ((R, u), (dR, r), (self.R1, t))), ('Br', ((R, r), (2 * dR, lap))),
                            ('Bz', ((R, z),)), ('BL', ((R, lap),))):
            given = [c * P for c, P in pairs if P is not None]
            if given:
                Y[name] = w * sum(given)
        return self.scale * self.products.adjoint(Y)

    # -- functionals ---------------------------------------------------------------
    def _integrals(self, u, ur, uz, ut, W):
        """Local parts of (E, A, V - |Omega|/2, M)."""
        w, eps = self.ops.w, self.eps
        mean = lambda X: np.dot(w, X.mean(axis=1))  # noqa: E731
        return np.array([F_E * self.k / (2 * eps) * mean(W * W),
                         F_A * mean(0.5 * eps * (ur * ur + uz * uz + ut * ut)
                                    + (u * u - 1.0) ** 2 / (4 * eps)),
                         0.5 * mean(u), mean(u * (self.ops.z - self.zc)[:, None])])

    def values(self, x):
        """Local parts of (E, A, V - |Omega|/2, M)."""
        u, ur, uz, ut, lap = self.fields(x)
        return self._integrals(u, ur, uz, ut, self._W(u, lap)[0])

    def gradients(self, x):
        """Local values and the gradients of E and A (flat, as x)."""
        u, ur, uz, ut, lap = self.fields(x)
        W, dW, _ = self._W(u, lap)
        eps, cE = self.eps, F_E * self.k / (2 * self.eps)
        p = self._project
        gE = self._adjoint(u=2 * cE * p(W * dW), lap=2 * cE * eps * p(W))
        a = F_A * eps
        gA = self._adjoint(u=F_A * p((u ** 3 - u) / eps), r=a * p(ur), z=a * p(uz),
                           t=a * p(ut, True))
        return self._integrals(u, ur, uz, ut, W), gE.ravel(), gA.ravel()

    def _second_variation(self, x, sigma):
        """The coefficients of the second variation of E - sigma A at x, per
        quadrature point and theta point: (K_uu, K_ul, K_ll, K_grad) of

            K_uu du^2 + 2 K_ul du dLap + K_ll dLap^2 + K_grad |grad du|^2,

        from E's (eps Lap u + W(u))^2 / eps and A's double well and gradient;
        K_ll and K_grad are constants."""
        u, _, _, _, lap = self.fields(x)
        W, dW, d2W = self._W(u, lap)
        eps, c = self.eps, F_E * self.k / self.eps       # c = 2 cE
        return (c * (dW * dW + W * d2W) - sigma * F_A * (3 * u * u - 1.0) / eps,
                c * eps * dW, c * eps * eps, -sigma * F_A * eps)

    def linearization(self, x, sigma):
        """v -> (Hess E - sigma Hess A) v at x (local contributions, flat; V
        and M are linear): the state's coefficients computed once for every
        product of a Krylov solve, the coupled Hessian never formed."""
        uu, ul, ll, grad = self._second_variation(x, sigma)
        p = self._project

        def action(v):
            du, dur, duz, dut, dlap = self.fields(v, offsets=False)
            return self._adjoint(u=p(uu * du + ul * dlap), r=grad * p(dur), z=grad * p(duz),
                                 t=grad * p(dut, True), lap=p(ul * du + ll * dlap)).ravel()
        return action

    def coupled_hessian(self, x, sigma):
        """The exact local Hessian of E - sigma A at x, every pair of
        harmonics coupled (CSR on `coupled_pattern`): the form of
        `linearization` assembled, sum over the field pairs (f, g) of
        E_f^j^T diag(w mean_theta(K_fg tau_f^j tau_g^k)) E_g^k, with E_f^j
        harmonic j's map chi_j -> field f / T_j (`_field_operators`) and tau =
        T_j (T_j' for u_theta / r). nh^2 times the axisymmetric Hessian's
        entries: for a factorization that must be exact (an index,
        `parallel.harmonic`), not for the Krylov solves."""
        uu, ul, ll, grad = self._second_variation(x, sigma)
        pairs = (('u', 'u', uu), ('u', 'l', ul), ('l', 'u', ul), ('l', 'l', ll),
                 ('r', 'r', grad), ('z', 'z', grad), ('t', 't', grad))
        o, h, nh = self.ops, self.h, len(self.h)
        diag = scipy.sparse.diags
        E = self._field_operators()
        tau = {f: (h.dT if f == 't' else h.T) for f in 'uzrlt'}
        # block (j, k) at rows nh a + j, columns nh b + k; (k, j) its transpose
        rows, cols, data = [], [], []
        for j in range(nh):
            for k in range(j, nh):
                block = 0
                for f, g, K in pairs:
                    mean = np.mean(np.asarray(K) * tau[f][:, j] * tau[g][:, k], axis=-1)
                    if np.any(mean):
                        block = block + E[j][f].T @ diag(o.w * mean) @ E[k][g]
                if np.isscalar(block):
                    continue
                B = block.tocoo()
                for a, b, first, second in ((B.row, B.col, j, k), (B.col, B.row, k, j))[:1 + (k > j)]:
                    rows.append(nh * a + first)
                    cols.append(nh * b + second)
                    data.append(B.data)
        P = self.coupled_pattern()
        # onto the pattern, its structural zeros kept
        H = scipy.sparse.csr_matrix((np.concatenate(data), (np.concatenate(rows),
                                                            np.concatenate(cols))),
                                    shape=P.shape) + P
        H.sort_indices()
        if H.nnz != P.nnz:
            raise RuntimeError("the coupled Hessian leaves its pattern")
        return self._scaled(H)

    def _scaled(self, K):
        """S K S for a local matrix K in chi on `pattern` (interleaved, nh a + j): K in
        x. The factors s_row s_col, one per entry of the pattern, are computed once."""
        if self._factors is None:
            s = self.scale.ravel()
            rows = np.repeat(np.arange(K.shape[0]), np.diff(K.indptr))
            self._factors = s[rows] * s[K.indices]
        K.data *= self._factors
        return K

    def _field_operators(self):
        """Per harmonic j the sparse maps chi_j -> (u, u_r, u_z, u_theta / r,
        Lap u) / T_j at the quadrature points, keyed 'u r z t l'; built once."""
        if self._E is None:
            o, R, dR, R1 = self.ops, self.R, self.dR, self.R1
            diag = scipy.sparse.diags
            self._E = [dict(u=diag(R[:, j]) @ o.B0, z=diag(R[:, j]) @ o.Bz,
                            t=diag(R1[:, j]) @ o.B0,
                            r=diag(R[:, j]) @ o.Br + diag(dR[:, j]) @ o.B0,
                            l=diag(R[:, j]) @ o.BL + diag(2 * dR[:, j]) @ o.Br)
                       for j in range(len(self.h))]
        return self._E

    def coupled_pattern(self):
        """The sparsity of `coupled_hessian`: the grid's Hessian pattern for
        every pair of harmonics, interleaved (nh a + j)."""
        if self._coupled is None:
            P, nh = self._gram().pattern, len(self.h)
            K = scipy.sparse.kron(P, np.ones((nh, nh)), format='csr')
            K.sort_indices()
            self._coupled = scipy.sparse.csr_matrix(
                (np.zeros(K.nnz), K.indices, K.indptr), shape=K.shape)
        return self._coupled

    def max_abs(self, x):
        """max |phi_h| over the local quadrature points and theta points."""
        return float(np.abs(self.fields(x)[0]).max(initial=0.0))

    # -- the block-diagonal Hessian --------------------------------------------------
    def pattern(self):
        """The sparsity of `hessian` in the interleaved numbering (node a,
        harmonic j) -> nh a + j: the grid's Hessian pattern once per harmonic
        (block-diagonal), or for every pair (`coupled`)."""
        return self.coupled_pattern() if self.coupled else self._interleave()[0]

    def _interleave(self):
        if self._interleaved is None:
            P, nh = self._gram().pattern, len(self.h)
            counts = np.diff(P.indptr)
            row = np.repeat(np.arange(len(counts)), counts)
            first = P.indptr[row]
            j = np.arange(nh)
            # entry e of row a in harmonic j sits at nh p0 + j c_a + (e - p0)
            where = (nh * first[:, None] + j * counts[row][:, None]
                     + (np.arange(P.nnz) - first)[:, None])
            indptr = np.concatenate([[0], np.cumsum(np.repeat(counts, nh))])
            indices = np.empty(P.nnz * nh, dtype=P.indices.dtype)
            indices[where] = nh * P.indices[:, None] + j
            K = scipy.sparse.csr_matrix((np.zeros(P.nnz * nh), indices, indptr),
                                        shape=(nh * P.shape[0], nh * P.shape[1]))
            self._interleaved = (K, where)
        return self._interleaved

    def hessian(self, x, sigma):
        """Local block-diagonal Hessian diag(H_m) of the theta-averaged state
        chi_0 (`azimuthal.ModeForms`, sines and cosines of one m sharing H_m),
        on `pattern`: at an axisymmetric state the exact Hessian of
        E - sigma A, elsewhere the Krylov solver's preconditioner; with
        `coupled` the exact one (`coupled_hessian`)."""
        if self.coupled:
            return self.coupled_hessian(x, sigma)
        gram = self._gram()
        chi0 = np.reshape(x, self.shape)[:, 0]  # the scale of m = 0 is 1
        forms = ModeForms(self.ops, gram, gram.blocks(OPERATORS), chi0, self.eps, self.k,
                          self.c0, sigma, self.zc)
        blocks = {m: forms.hessian(m).data for m in np.unique(self.h.m)}
        K, where = self._interleave()
        K = K.copy()
        K.data[where] = np.column_stack([blocks[m] for m in self.h.m])
        return self._scaled(K)
