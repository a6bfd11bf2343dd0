"""Second variation of the Lagrangian in one azimuthal mode, on rank-local arrays.

A perturbation delta phi = psi(r, z) cos(m theta) of an axisymmetric phi
decouples from every other m. With L = E - nu . (c - c0) its second variation
is a quadratic form in psi on the (r, z) grid:

    d2L_m[psi] = t_m int [ 2 cE ((eps Lap_m psi + W' psi)^2 + W W'' psi^2)
                           - nu_A f_A ( eps (psi_r^2 + psi_z^2 + m^2 psi^2 / r^2)
                                        + (3 phi^2 - 1) psi^2 / eps ) ] r dr dz

with cE = f_E k / (2 eps), Lap_m psi = psi_rr + psi_r / r + psi_zz - m^2 psi / r^2
and t_m = int cos^2(m theta) dtheta = 2 pi for m = 0, pi for m >= 1: the
weights w of the operators (which hold 2 pi r) times THETA[m] (1, then 1/2).
V and M are linear in phi and add nothing; for m >= 1 the first variations of
A, V and M integrate cos(m theta) to zero, so the constraints drop out.

The axis. A smooth 3D field psi(r, z) cos(m theta) has psi = r^m g(r^2, z)
near r = 0, g smooth: psi has the parity (-1)^m in r and vanishes to order m.
The solver's basis is even in r (the nodes near the axis are mirrored to
r < 0 and folded onto their originals), and on the folded basis the axis is
interior, not on the hull: there the axis nodes carry about a quarter of the
weight (0.74-0.76 belongs to their neighbours at r ~ h / 2 and their mirrors),
so zeroing the axis coefficients does not make psi_h vanish on the axis. An
even psi_h with psi_h(0) != 0 makes int m^2 psi^2 / r dr diverge, one with
psi_h = c r^2 cannot follow the psi ~ r of an odd mode (m = 1: a boundary
layer whose energy shrinks only slowly with h), and an odd basis meets the same
problem at m = 3, 5 (psi ~ r instead of r^3 makes (Lap_m psi)^2 r ~ 1 / r).
(Measured at eps 0.06 on 1,511 ... 6,111 nodes: with the even basis and the
axis coefficients zeroed, the m = 1 rotation comes out at 4.4 ... 3.6 instead
of ~0 and the first elastic m = 1 eigenvalue at 78 ... 73 instead of 56.3.)
So the mode is written psi = r^m chi with chi = sum_a chi_a p_a on the
solver's even basis: psi_h has the exact parity and order at the axis for
every m, every chi_a is free (the axis nodes included), and

    psi_r = r^m chi_r + m r^(m-1) chi,    m psi / r = m r^(m-1) chi,
    Lap_m psi = r^m (Lap chi + 2 m chi_r / r)   (the m^2 r^(m-2) chi terms cancel),

all rows of the existing operators scaled point by point, so the batched Gram
products of the grid assemble H_m on the Hessian's own pattern. m = 0 is the
Hessian of the Lagrangian itself.
"""
import numpy as np

from pfmembrane.kernels.functionals import F_A, F_E, Functionals

# int cos^2(m theta) dtheta / (2 pi): the weights w already integrate 2 pi.
THETA = lambda m: 1.0 if m == 0 else 0.5  # noqa: E731
# Each mode's Hessian combines all four operators in one row (the Laplacian's
# r^m Lap + 2 m r^(m-1) d/dr): their blocks are kept for every m.
OPERATORS = ('B0', 'BL', 'Br', 'Bz')
RIGID = 0.5  # a mode with more than this fraction of its norm in rigid motions is one


class ModeForms:
    """Local mode Hessians H_m and mass products M_m chi at one state.

    Not collective. `ops` and `gram` are one grid's rank-local operators and
    Gram products, `dense` their blocks of `OPERATORS` (`Gram.blocks`); `phi`
    the local nodal values (ghosts included), `nu_area` the tension nu_A of
    L = E - nu . (c - c0). The unknowns are the nodal coefficients chi_a of
    psi = r^m chi.
    """

    def __init__(self, ops, gram, dense, phi, eps, k, c0, nu_area, zc):
        self.ops, self.gram, self.dense = ops, gram, dense
        self.eps, self.zc = eps, zc
        forms = Functionals(ops, eps, k, c0, zc)
        u, self.ur, self.uz, lap = forms.fields(phi)
        W, self.dW, d2W = forms._W(u, lap)   # W, dW/dphi, d2W/dphi2: the solver's own
        cE = F_E * k / (2 * eps)
        self.bend = 2 * cE * ops.w                          # times (eps Lap_m psi + W' psi)^2
        self.value = ops.w * (2 * cE * W * d2W - nu_area * F_A * (3 * u * u - 1.0) / eps)
        self.stretch = -nu_area * F_A * eps * ops.w          # times |grad psi|^2

    def powers(self, m):
        """r^m and m r^(m-1) at the quadrature points (all at r > 0)."""
        r = self.ops.r
        return r ** m, m * r ** (m - 1) if m else np.zeros_like(r)

    def terms(self, m, shift=0.0):
        """The (coefficients, weights) of d2L_m - shift t_m int psi^2 for
        `gram.upper_data`.

        Rows of one operator fold their coefficient into the weight, so the
        psi^2 terms (W W'', the area's double well, m^2 psi^2 / r^2 and the
        shift's mass) make one term; at m = 0 the r^(m-1) coefficients vanish
        and d2L_0 is the Hessian of `Functionals.hessian`.
        """
        t, eps, w = THETA(m), self.eps, self.ops.w
        rm, drm = self.powers(m)
        return [({'BL': eps * rm, 'Br': 2 * eps * drm, 'B0': self.dW * rm}, t * self.bend),
                ({'Br': rm, 'B0': drm}, t * self.stretch),                       # psi_r
                ({'Bz': 1.0}, t * self.stretch * rm * rm),                        # psi_z
                ({'B0': 1.0}, t * ((self.value - shift * w) * rm * rm + self.stretch * drm * drm))]

    def hessian(self, m, shift=0.0):
        """Local H_m - shift M_m (CSR on the grid's Hessian pattern)."""
        return self.gram.full(self.gram.upper_data(self.terms(m, shift), self.dense))

    def mass_weights(self, m):
        """t_m w r^(2m): M_m = B0^T diag(t_m w r^(2m)) B0 is the L2 mass of the
        3D perturbation, t_m int psi^2 r dr dz."""
        return THETA(m) * self.ops.w * self.powers(m)[0] ** 2

    def mass(self, chi, weights):
        """M_m chi (local contributions, ghosts included) for `mass_weights(m)`."""
        B0 = self.ops.B0
        return B0.T @ (weights * (B0 @ chi))

    def field(self, chi, m):
        """psi_h = r^m chi_h at the local quadrature points."""
        return self.powers(m)[0] * (self.ops.B0 @ chi)

    def rigid(self, m):
        """The fields of the rigid motions in mode m at the quadrature points:
        for m = 0 the translation along the axis (phi_z), which the moment
        constraint M = 0 pins; for m = 1 those that move the shape off its
        axis, the translation along x (d phi / dx = phi_r cos theta) and the
        rotation about the y axis through (0, zc) ((z - zc) d/dx - x d/dz:
        ((z - zc) phi_r - r phi_z) cos theta); none for m >= 2."""
        o = self.ops
        return {0: [self.uz], 1: [self.ur, (o.z - self.zc) * self.ur - o.r * self.uz]}.get(m, [])
