"""The Du-Liu-Wang functionals E, A, V, M on rank-local arrays.

Pure numpy/scipy: values, gradients (local nodal arrays, ghosts included) and
Hessians (local CSR) from the operators of one grid. Sums over this rank's
quadrature points only; the assembly layer adds the ranks together.
"""
import numpy as np

F_E = 3.0 / (8.0 * np.sqrt(2.0))
F_A = 3.0 / (2.0 * np.sqrt(2.0))
SQRT2 = np.sqrt(2.0)


class Functionals:
    """E, A, V, M of one scene on one grid (rank-local parts).

    Not collective. The gradients of V and M and the stiffness part of the
    Hessian of A do not depend on phi and are computed once. `gram` returns
    the `gram.Gram` of the same operators; only `hessian` calls it.
    """

    def __init__(self, ops, eps, k=1.0, c0=0.0, zc=1.0, gram=None):
        self.ops, self.eps, self.k, self.c0, self.zc = ops, eps, k, c0, zc
        self._gram = gram
        w = ops.w
        self.grad_V = 0.5 * (ops.B0.T @ w)
        self.grad_M = ops.B0.T @ (w * (ops.z - zc))
        self._stiffness = None

    @property
    def gram(self):
        return self._gram()

    @property
    def stiffness(self):
        """eps f_A int grad p_a . grad p_b (the constant part of Hess A), as
        upper-pattern data of `gram`, built on demand."""
        if self._stiffness is None:
            g, s = self.gram, self.eps * F_A * self.ops.w
            self._stiffness = g.upper_data([({'Br': 1.0}, s), ({'Bz': 1.0}, s)],
                                           blocks=g.blocks(('Br', 'Bz')))
        return self._stiffness

    def fields(self, phi):
        """Value, gradient and Laplacian of phi_h at the quadrature points."""
        o = self.ops
        return (o.B0 @ phi + o.b0, o.Br @ phi + o.br, o.Bz @ phi + o.bz, o.BL @ phi + o.bL)

    def _W(self, u, lap):
        eps, s = self.eps, SQRT2 * self.c0
        W = eps * lap + (u / eps + s) * (1.0 - u * u)
        dW = 1.0 / eps - 3.0 * u * u / eps - 2.0 * s * u      # dW/du
        d2W = -6.0 * u / eps - 2.0 * s                         # d2W/du2
        return W, dW, d2W

    def _integrals(self, u, ur, uz, W):
        """Local parts of (E, A, V - |Omega|/2, M) from the fields."""
        w, eps = self.ops.w, self.eps
        return np.array([F_E * self.k / (2 * eps) * np.dot(w, W * W),
                         F_A * np.dot(w, 0.5 * eps * (ur * ur + uz * uz)
                                      + (u * u - 1.0) ** 2 / (4 * eps)),
                         0.5 * np.dot(w, u), np.dot(w, u * (self.ops.z - self.zc))])

    def values(self, phi):
        """Local parts of (E, A, V - |Omega|/2, M)."""
        u, ur, uz, lap = self.fields(phi)
        return self._integrals(u, ur, uz, self._W(u, lap)[0])

    def gradients(self, phi):
        """Local values (E, A, V - |Omega|/2, M) and gradients of E and A."""
        o, eps = self.ops, self.eps
        u, ur, uz, lap = self.fields(phi)
        w = o.w
        W, dW, _ = self._W(u, lap)
        cE = F_E * self.k / (2 * eps)
        gE = 2 * cE * (eps * (o.BL.T @ (w * W)) + o.B0.T @ (w * W * dW))
        gA = F_A * (eps * (o.Br.T @ (w * ur) + o.Bz.T @ (w * uz))
                    + o.B0.T @ (w * (u ** 3 - u) / eps))
        return self._integrals(u, ur, uz, W), gE, gA

    def hessian(self, phi, sigma):
        """Local Hess E - sigma Hess A (V and M are linear), as CSR."""
        o, eps = self.ops, self.eps
        u, _, _, lap = self.fields(phi)
        w = o.w
        W, dW, d2W = self._W(u, lap)
        cE = F_E * self.k / (2 * eps)
        # Hess E = 2 cE D^T w D + B0^T (2 cE w W W'') B0 with D = eps BL + W' B0;
        # Hess A = stiffness + B0^T (f_A w (3u^2 - 1) / eps) B0.
        c0 = 2 * cE * w * W * d2W - sigma * F_A * w * (3 * u * u - 1.0) / eps
        H = self.gram.upper_data([({'BL': eps, 'B0': dW}, 2 * cE * w), ({'B0': 1.0}, c0)])
        if sigma != 0.0:
            H = H - sigma * self.stiffness
        return self.gram.full(H)
