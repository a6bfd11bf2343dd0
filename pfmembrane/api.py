"""The public API: a scene, a grid built once, solves on it and their results.

Grids, solves and adaptation are collective on the grid's communicator
(PETSc's COMM_WORLD unless given). PETSc starts on first use: with the
script's command-line arguments, so `-log_view` or `-info` reach it, except
in an interactive session or a notebook, whose arguments are not PETSc's.
Reading a result, and `Scene`, need no PETSc at all.
"""
import itertools
import math
import resource
import sys
import time
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from pfmembrane.io import checkpoint, options as appoptions
from pfmembrane.io.options import Params, Targets
from pfmembrane.kernels import adapt as adaptivity, nodes as nodesets
from pfmembrane.kernels.basis import locality
from pfmembrane.kernels import initial
from pfmembrane.kernels.nodes import spacing_peak

__all__ = ['Scene', 'Grid', 'Result', 'solve', 'adapt', 'read', 'predict', 'tangent', 'along',
           'continuation', 'stability']

# eps >= RESOLUTION * h_min, h_min the left peak of the mean-neighbour-distance
# distribution: calibrated on the paper's Tables 1-5 (admitted eps/h = 1.67-1.76,
# refused 1.18-1.25).
RESOLUTION = 1.5
# Log events whose times a result reports: functionals and their derivatives
# into Vec/Mat, and the linear solves (factorizations included).
ASSEMBLY_EVENTS = ('pfFunctional', 'pfGradient', 'pfHessian', 'pfMatAssembly')
LINEAR_EVENTS = ('PCSetUp', 'KSPSolve')
MULTIPLIERS = ('nu_area', 'nu_volume', 'nu_moment')
# Resampling of a sharp start's curve, in eps: its distances err by less than
# 1/64 eps on the membrane, 1% of the tanh profile's slope.
CURVE_SPACING = 1.0 / 32


def petsc(args=None):
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


def _comm(comm):
    """A PETSc communicator from None (COMM_WORLD), an mpi4py or a PETSc one."""
    PETSc = petsc()
    if comm is None:
        return PETSc.COMM_WORLD
    return comm if isinstance(comm, PETSc.Comm) else PETSc.Comm(comm)


@dataclass(frozen=True)
class Scene(Targets):
    """The vesicle: A0 = 4 pi R^2, V0 = v 4/3 pi R^3, bending rigidity k,
    spontaneous curvature c0, the (r, z) box (Rb, Zb) or 'auto', the family
    of the initial guess, and whether it is solved on the half box z >= Zb/2."""
    reduced_volume: float = Params.reduced_volume
    c0: float = Params.c0
    radius: float = Params.radius
    k: float = Params.k
    box: tuple = Params.box
    branch: str = Params.branch
    symmetric: bool = Params.symmetric

    def __post_init__(self):
        if self.box != 'auto':
            object.__setattr__(self, 'box', tuple(float(b) for b in self.box))
        appoptions.check_scene(self)

    @property
    def zc(self):
        return 0.5 * self.box[1]

    @property
    def plane(self):
        """z of the mirror plane of a half-box solve, None on the full box."""
        return self.zc if self.symmetric else None

    def sized(self, eps):
        """This scene in the box of `-pf_box auto` for `eps` (`analysis.sizing`),
        or unchanged if it has a box."""
        if self.box != 'auto':
            return self
        from pfmembrane.analysis.sizing import auto_box
        unbounded = SimpleNamespace(**{f: getattr(self, f) for f in
                                       ('radius', 'reduced_volume', 'branch', 'area', 'volume',
                                        'c0', 'k')},
                                    box=(math.inf, math.inf))
        appoptions.check_fits(unbounded, eps)  # refuses a scene without a start
        return replace(self, box=auto_box(self.branch, self.reduced_volume, eps, self.radius,
                                          self.c0, self.k))

    @classmethod
    def of(cls, attrs):
        """The scene of checkpoint attributes."""
        return cls(reduced_volume=float(attrs['reduced_volume']), c0=float(attrs['c0']),
                   radius=float(attrs['radius']), k=float(attrs['k']),
                   box=tuple(float(b) for b in attrs['box']), branch=str(attrs['branch']),
                   symmetric=bool(attrs.get('symmetric', 0)))


class Grid:
    """Nodes of a scene's box with their max-ent basis, partition, operators
    and Hessian products, built once and reused by every solve on it.

    Collective on `comm`. `gamma` is the max-ent locality (beta_a = gamma /
    h_a^2), `cutoff` the support cut-off, `quad_degree` the Gauss rule on the
    Delaunay triangles, `spacing_smoothing` the passes over h_a behind beta_a,
    `spacing_floor` the quantile Q of the smoothed h_a below which beta_a stays
    gamma / h_Q^2 (0: none; graded grids, `basis.spacing_and_locality`),
    `partition` the split of the nodes among the ranks (`parallel.partition`).
    """

    def __init__(self, scene, nodes, gamma=Params.gamma, cutoff=Params.cutoff,
                 quad_degree=Params.quad_degree, spacing_smoothing=Params.spacing_smoothing,
                 spacing_floor=Params.spacing_floor, partition=Params.partition, comm=None):
        from pfmembrane.parallel.discretization import Grid as Discretization
        PETSc = petsc()
        if scene.box == 'auto':
            raise ValueError("the scene's box is 'auto': size it first (Scene.sized(eps))")
        self.comm = _comm(comm)
        self.box, self.symmetric, self.plane = scene.box, scene.symmetric, scene.plane
        self.params = dict(gamma=gamma, cutoff=cutoff, quad_degree=quad_degree,
                           spacing_smoothing=spacing_smoothing, spacing_floor=spacing_floor,
                           partition=partition)
        self.adapt_info, self._transferred = None, None
        t0 = time.perf_counter()
        stage = PETSc.Log.Stage('pfBasis')
        stage.push()
        try:
            self.discrete = Discretization(self.comm, np.asarray(nodes, dtype=float), scene.box,
                                           gamma, cutoff, quad_degree, spacing_smoothing,
                                           scene.plane, partition, spacing_floor)
            self.discrete.gram  # stage 2 always needs the Hessian
        finally:
            stage.pop()
        self.setup_time = time.perf_counter() - t0
        self._setup_pending = True  # the first solve reports the set-up time
        self.eps_min = RESOLUTION * spacing_peak(self.discrete.h)

    @classmethod
    def uniform(cls, scene, nodes=Params.nodes, **kwargs):
        """A near-hexagonal grid of about `nodes` nodes of the full box (its
        half with the scene's mirror plane), nodes on every edge."""
        return cls(scene, nodesets.uniform(scene.box, nodes, half=scene.symmetric), **kwargs)

    @classmethod
    def of(cls, result, comm=None, **kwargs):
        """The grid of a result's nodes, with its basis parameters unless given."""
        return cls(result.scene, result.nodes, **{**result.basis, **kwargs}, comm=comm)

    @property
    def nodes(self):
        return self.discrete.nodes

    @property
    def n_nodes(self):
        return len(self.discrete.nodes)

    def fits(self, scene):
        """Whether `scene` can be solved on this grid: same box and symmetry."""
        return (scene.box != 'auto' and np.allclose(scene.box, self.box, rtol=0, atol=1e-12)
                and scene.symmetric == self.symmetric)

    def __repr__(self):
        d = self.discrete
        return (f"Grid({self.n_nodes} nodes, {d.layout.nglobal} free, {d.nquad} quadrature "
                f"points, gamma {self.params['gamma']:g}, eps_min {self.eps_min:.4g})")


@dataclass
class Result:
    """A solved (or stopped) state: nodes and nodal phi on every rank, and the
    checkpoint attributes (`io.checkpoint`): energy, area, volume, moment, the
    multipliers, eps, the scene, converged, times. `grid` is the grid it was
    solved on (None for a result read from a file)."""
    nodes: np.ndarray
    phi: np.ndarray
    attrs: dict
    grid: object = None
    message: str = ''
    status: int = 0
    path: str = ''
    datasets: dict = field(default_factory=dict)

    @property
    def energy(self):
        return float(self.attrs['energy'])

    @property
    def eps(self):
        return float(self.attrs['eps'])

    @property
    def converged(self):
        return bool(self.attrs['converged'])

    @property
    def nu(self):
        """Multipliers (nu_A, nu_V[, nu_M]): L = E - nu . (c - c0)."""
        n = 2 if self.attrs.get('symmetric', 0) else 3
        return np.array([float(self.attrs.get(k, 0.0)) for k in MULTIPLIERS[:n]])

    @property
    def scene(self):
        return Scene.of(self.attrs)

    @property
    def basis(self):
        """The basis parameters it was solved with (`Grid`'s keywords)."""
        return checkpoint.basis(self.attrs)

    def locality(self, plane=None):
        """beta_a of its basis at its nodes (`plane`: the mirror plane of a half box):
        its grid's, when it has its grid."""
        if self.grid is not None and self.grid.discrete.plane == plane:
            return self.grid.discrete.beta
        b = self.basis
        return locality(self.nodes, b['gamma'], b['spacing_smoothing'], plane,
                        b['spacing_floor'])

    def checkpoint(self):
        return checkpoint.Checkpoint(self.nodes, self.phi, self.attrs, self.datasets)

    def unfolded(self):
        """This state on the full box: a half-box result with its mirror image, on its
        nodes and their images (a start for a full-box solve on those nodes, where the
        up-down symmetry is free to break: an up-down symmetric grid keeps a pitchfork a
        pitchfork); a full-box one unchanged."""
        if not self.attrs.get('symmetric', 0):
            return self
        ck = self.checkpoint().unfolded()
        return Result(ck.nodes, ck.phi, ck.attrs, message=self.message, status=self.status)

    def save(self, path):
        """Write the checkpoint and its `.xdmf` beside it, atomically.

        Collective on the grid's communicator (serial for a result read back).
        """
        comm = self.grid.comm.tompi4py() if self.grid is not None else None
        triangles = (self.grid.discrete.triangles if self.grid is not None
                     else self.datasets.get('triangles'))
        checkpoint.write(path, self.nodes, self.phi, self.attrs, comm=comm,
                         datasets={k: v for k, v in self.datasets.items() if k != 'triangles'},
                         triangles=triangles)
        self.path = str(path)
        return self


def read(path, comm=None, expect_box=None):
    """The result stored in a checkpoint; collective when `comm` (mpi4py or
    PETSc) is given. `expect_box`: (Rb, Zb) it must have."""
    if comm is not None and hasattr(comm, 'tompi4py'):
        comm = comm.tompi4py()
    ck = checkpoint.read(path, comm, expect_box=expect_box)
    return Result(ck.nodes, ck.phi, ck.attrs, path=str(path), datasets=ck.datasets)


def adapt(result, f, comm=None, along=(), band=0.0, **grid_params):
    """A grid of as many nodes as `result`'s, relocated by CVT for the density
    1 + f |grad phi_h| (paper Section 4.2), with its basis parameters unless
    given. A solve on it started from `result` uses phi_h transferred to the
    new nodes. `along`: results on `result`'s nodes (the points of a branch)
    whose interfaces the grid follows too, by the largest |grad phi_h| of
    them all. `band` > 0: |grad phi_h| replaced by its largest value within
    that distance, so the nodes are evenly spaced across the interfaces and
    graded only where phi_h is near +-1. Collective."""
    PETSc = petsc()
    comm = _comm(comm if comm is not None else
                 (result.grid.comm if result.grid is not None else None))
    scene, basis = result.scene, result.basis
    stage = PETSc.Log.Stage('pfAdapt')
    stage.push()
    try:
        if any(not np.array_equal(r.nodes, result.nodes) for r in along):
            raise ValueError("adapt along results on other nodes")
        xy, phi, info = adaptivity.relocate(comm.tompi4py(), result.nodes, result.phi,
                                            scene.box, result.locality(scene.plane),
                                            basis['cutoff'], f, scene.plane,
                                            np.array([r.phi for r in along]) if along else None,
                                            band)
    finally:
        stage.pop()
    of = (result.path or 'the result') + (f" and {len(along)} more" if along else '')
    PETSc.Sys.Print(f"adapt: CVT f={f:g}{f' band={band:g}' if band else ''} of {of}: "
                    f"{info['iterations']} "
                    f"Lloyd steps (movement {info['movement']:.1e}), h_min {info['h_min'][0]:.4g}"
                    f" -> {info['h_min'][1]:.4g}, raster {info['raster'][1]}x{info['raster'][0]}, "
                    f"{info['time']:.2f} s", comm=comm)
    grid = Grid(scene, xy, **{**basis, **grid_params}, comm=comm)
    grid.adapt_info, grid._transferred = info, (result, phi)
    return grid


def predict(older, newer, ratio=1.0):
    """The secant predictor of a continuation: phi and the multipliers of
    `newer` + `ratio` (`newer` - `older`), a start for the next solve on
    `newer`'s grid (`ratio`: the next parameter step over the last one)."""
    if older.nodes.shape != newer.nodes.shape or not np.array_equal(older.nodes, newer.nodes):
        raise ValueError("predict needs two results on the same nodes")
    phi = newer.phi + ratio * (newer.phi - older.phi)
    nu = newer.nu + ratio * (newer.nu - older.nu)
    attrs = {**newer.attrs, **dict(zip(MULTIPLIERS, nu)), 'converged': 1}
    return Result(newer.nodes, phi, attrs, grid=newer.grid, path=newer.path)


class Tangent(NamedTuple):
    """d(phi, nu)/dp along a branch: `phi` nodal (0 on the Dirichlet nodes)."""
    parameter: str
    phi: np.ndarray
    nu: np.ndarray


# Scene parameters a branch can follow (`Solver.tangent`, `Solver.arclength`).
CONTINUATION = ('reduced_volume', 'c0', 'radius')
# A continuation step is retried at half the length when its corrector needs more than
# CORRECTOR_MAX_IT Newton steps (factorizations; 3-4 on a regular stretch, then chord
# steps) or lands farther than JUMP steps from the last point: both are how a long step
# onto another branch shows (runs/atlas/notes.md).
CORRECTOR_MAX_IT = 7
JUMP = 2.0
GROW_IT = 3  # a corrector of at most this many factorizations lets the next step grow


class _Branch:
    """A converged result's state as distributed Vecs, with a solver whose
    problem `at(p)` moves to parameter value p. Collective; `close` frees it
    and the options of its prefix."""

    def __init__(self, result, parameter, options, prefix):
        from pfmembrane.parallel.assembly import Problem
        from pfmembrane.parallel.solver import Solver
        if parameter not in CONTINUATION:
            raise ValueError(f"no continuation in {parameter!r}: one of "
                             f"{', '.join(CONTINUATION)}")
        if result.grid is None or not result.converged:
            raise ValueError("a branch starts from a converged result on its grid (a solve's)")
        PETSc = petsc()
        self.result, self.parameter, self.grid = result, parameter, result.grid
        self.scene = scene = result.scene
        lay = self.grid.discrete.layout
        self.P = Problem(self.grid.discrete, result.eps, scene.k, scene.c0,
                         (scene.area, scene.volume), scene.zc)
        self.x = self.P.create_vec()
        self.x.setArray(result.phi[lay.order[lay.start:lay.start + lay.nowned]])
        self.prefix = f"pf{next(_solve_count)}_" if prefix is None else prefix
        self._options = _options(options, self.prefix)
        self._options.__enter__()
        self.solver = Solver(self.P, appoptions.read_settings(PETSc.Options(), self.prefix),
                             self.prefix)
        self.solver.nu = result.nu
        self.checked = {}  # what `phase_field_checks` keeps between this branch's points

    def at(self, value):
        """Put the problem at `value` of the parameter: its targets and C0. Not a
        Scene: a corrector's iterate may pass where no scene is (v > 1)."""
        p = {name: getattr(self.scene, name) for name in CONTINUATION}
        p[self.parameter] = value
        self.P.targets[:2] = appoptions.targets(p['radius'], p['reduced_volume'])
        self.P.forms.c0 = p['c0']

    def close(self):
        self.solver.destroy()
        for key in self.solver.defaults:
            petsc().Options().delValue(key)
        self._options.__exit__(None, None, None)


def tangent(result, parameter='reduced_volume', options=None, prefix=None):
    """The tangent of `result`'s branch in a scene parameter (`CONTINUATION`):
    dX/dp from one Jacobian factorization at the converged state
    (`Solver.tangent`). Collective on the result's grid. `options` as for
    `solve` (the factorization reads `stage2_` options under the prefix)."""
    branch = _Branch(result, parameter, options, prefix)
    try:
        (dx, dnu), _ = branch.solver.tangent(branch.x, getattr(branch.scene, parameter),
                                             branch.at)
        return Tangent(parameter, branch.grid.discrete.layout.nodal(dx, 0.0), dnu)
    finally:
        branch.close()


def continuation(result, parameter, ds, steps, ds_max=None, options=None, prefix=None,
                 checks=True, switch=False):
    """Pseudo-arclength continuation of `result`'s branch in a scene parameter
    (`CONTINUATION`), in this process on the result's grid. Collective.

    Yields a `Result` per point, `steps` of them or fewer should the step
    have to shrink below ds / 64. The arclength s is measured in the norm
    |(x, p)|^2 = x . x / n + p^2 of the n free nodal values x (their RMS) and
    the parameter p (`Solver.arclength`), the first step in the direction
    of increasing parameter for ds > 0. The step grows by 1.5 after a
    corrector of at most GROW_IT factorizations (to `ds_max`, by default 4 |ds|)
    and halves after a failed one (`CORRECTOR_MAX_IT`, `JUMP`). Each result's
    attrs carry the parameter, `arclength`, `index_0` (negative eigenvalues
    of the Hessian of the Lagrangian on the constraints' tangent space: the
    factorization's inertia minus the constraints), `dp_ds` and `fold` (1
    where dp/ds changed sign since the previous point) and `index_change` (1
    where index_0 changed without a fold: a bifurcation passed); `result`'s
    own attrs get its `index_0`, from the factorization of the first tangent.

    With `switch`, the branch left is the one crossing `result`'s at a
    bifurcation near it: the first tangent is the critical mode there (the
    eigenvector of that Hessian whose eigenvalue is nearest zero, `Solver.
    critical_mode`, stored as `result`'s attr `critical_eigenvalue`) with no
    parameter change, and ds > 0 and ds < 0 go to its two sides.
    """
    from pfmembrane.parallel.solver import SolveError
    branch = _Branch(result, parameter, options, prefix)
    solver, x = branch.solver, branch.x
    p = getattr(branch.scene, parameter)
    ds_max = ds_max or 4 * abs(ds)
    try:
        sign = 1.0 if ds > 0 else -1.0
        if switch:
            mx, mnu, value, negative = solver.critical_mode(x)
            mx.scale(sign)
            t = (mx, sign * mnu, 0.0)
            result.attrs['critical_eigenvalue'] = value
        else:
            (bx, bnu), negative = solver.tangent(x, p, branch.at)
            t = _unit(bx, bnu, sign)
        start = None if negative is None else negative - solver.ncon
        result.attrs['index_0'] = -1 if start is None else start
        step, s, previous = abs(ds), 0.0, (t[2], start)
        behind = None  # the point before this one and the step between them
        for _ in range(steps):
            x_old, nu_old = x.copy(), solver.nu.copy()
            try:
                p_new, its, factored, negative, (bx, bnu) = solver.arclength(
                    x, p, t, step, branch.at, CORRECTOR_MAX_IT, _bend(behind, x, nu_old, p, t, step))
                if _distance(x, x_old, p_new - p) > JUMP * step:
                    raise SolveError("the corrector left the step's neighbourhood")
            except SolveError:
                x_old.copy(x)
                solver.nu = nu_old
                branch.at(p)
                step /= 2
                if step < abs(ds) / 64:
                    warnings.warn(f"continuation in {parameter} stopped at {p:g}: the "
                                  f"corrector failed down to a step of {step:.3g}",
                                  stacklevel=2)
                    return
                continue
            s += step
            behind = (x_old, nu_old, p, step)
            p = p_new
            # the new tangent continues the old one: (b, 1) oriented by t
            t_new = _unit(bx, bnu, 1.0)
            if t[0].dot(t_new[0]) / x.getSize() + t[2] * t_new[2] < 0:
                t_new = _unit(bx, bnu, -1.0)
            index = None if negative is None else negative - solver.ncon
            fold = int(previous[0] != 0 and np.sign(t_new[2]) != np.sign(previous[0]))
            changed = int(previous[1] is not None and index is not None
                          and index != previous[1] and not fold)
            t, previous = t_new, (t_new[2], index)
            yield _point(branch, p, s, index, t_new[2], fold, changed, its, checks)
            step = min(1.5 * step, ds_max) if factored <= GROW_IT else step
    finally:
        branch.close()


def _bend(behind, x, nu, p, t, ds):
    """The second-order term of the predictor at (x, nu, p) with unit tangent t for
    a step ds: (ds / h)^2 (X_behind - X + h t), with X_behind the point a step h
    back, X(s - h) = X - h t + h^2 X'' / 2 + O(h^3). None for a branch's first
    step. It takes the corrector's start from O(ds^2) to O(ds^3) off the branch
    (runs/atlas/notes.md)."""
    if behind is None:
        return None
    xb, nub, pb, h = behind
    w = (ds / h) ** 2
    bx = xb.copy()
    bx.axpy(-1.0, x)
    bx.axpy(h, t[0])
    bx.scale(w)
    return bx, w * (nub - nu + h * np.asarray(t[1])), w * (pb - p + h * t[2])


def _distance(x, y, dp):
    """|(x - y, dp)| in the norm of `Solver.arclength`."""
    d = x.copy()
    d.axpy(-1.0, y)
    return math.hypot(d.norm() / math.sqrt(x.getSize()), dp)


def _unit(bx, bnu, sign):
    """The unit tangent (t_x, t_nu, t_p) along (sign b_x, sign b_nu, sign) in the
    norm of `Solver.arclength`."""
    norm = math.sqrt(bx.dot(bx) / bx.getSize() + 1.0)
    tx = bx.copy()
    tx.scale(sign / norm)
    return tx, sign * np.asarray(bnu) / norm, sign / norm


def _point(branch, p, s, index, dp_ds, fold, changed, its, checks):
    """The Result of a converged point of a continuation."""
    res, solver = branch.result, branch.solver
    vals = branch.P.values(branch.x)
    nu = solver.nu
    attrs = {**res.attrs, branch.parameter: p, 'energy': vals[0], 'area': vals[1],
             'volume': vals[2], 'moment': vals[3], **dict(zip(MULTIPLIERS, nu)),
             'converged': 1, 'arclength': s, 'index_0': -1 if index is None else index,
             'dp_ds': dp_ds, 'fold': fold, 'index_change': changed,
             'stage1_iterations': -1, 'stage2_iterations': its,
             'max_phi': branch.P.max_abs_phi(branch.x), 'parent': ''}
    for key in ('sharp_energy', 'sharp_rel_error', 'sharp_dist_max', 'sharp_dist_mean',
                'level_set_energy', 'topology', 'components', 'genus', 'torus_radii',
                'index_m', 'lowest_m', 'time_modes'):
        attrs.pop(key, None)
    phi = branch.grid.discrete.layout.nodal(branch.x, -1.0)
    if checks:
        attrs.update(phase_field_checks(branch.grid.comm.tompi4py(), branch.grid.nodes, phi,
                                        attrs, branch.checked))
    return Result(branch.grid.nodes, phi, attrs, grid=branch.grid)


def along(result, tangent, step):
    """The Euler predictor of a continuation: `result` moved by `step` in the
    tangent's parameter, a start for the solve there (on `result`'s grid)."""
    phi = result.phi + step * tangent.phi
    nu = result.nu + step * tangent.nu
    attrs = {**result.attrs, **dict(zip(MULTIPLIERS, nu)), 'converged': 1,
             tangent.parameter: float(result.attrs[tangent.parameter]) + step}
    return Result(result.nodes, phi, attrs, grid=result.grid, path=result.path)


def stability(result, modes=6, nev=3, prefix='modes_', grid=None):
    """The azimuthal stability of an axisymmetric `result` against
    perturbations psi(r, z) cos(m theta), m = 0 ... `modes`
    (`parallel.modes`). Collective on the grid's communicator (`grid`, else
    the result's, else one rebuilt from its nodes).

    Returns one `parallel.modes.Spectrum` per m, its `vectors` as nodal chi
    (psi = r^m chi_h) on every rank, and records in `result.attrs` the index
    per m without the rigid motions (`index_m`) and the lowest eigenvalue per
    m (`lowest_m`), which `save` writes to the checkpoint. The eigensolver
    reads its options under `prefix` (`-modes_eps_tol`).
    """
    from pfmembrane.kernels.modes import RIGID
    from pfmembrane.parallel.modes import ModeAnalysis
    grid = grid or result.grid or Grid.of(result)
    PETSc = petsc()
    stage = PETSc.Log.Stage('pfModes')
    stage.push()
    analysis = ModeAnalysis(grid, result.scene, result.eps, result.phi, result.nu[0], nev,
                            prefix)
    try:
        spectra = []
        for m in range(modes + 1):
            s = analysis.spectrum(m)
            spectra.append(s._replace(vectors=[grid.discrete.layout.nodal(chi, 0.0)
                                               for chi in s.vectors]))
    finally:
        analysis.destroy()
        stage.pop()
    result.attrs.update(
        index_m=np.array([s.index - np.count_nonzero((s.rigid > RIGID) & (s.eigenvalues < 0))
                          for s in spectra]),
        lowest_m=np.array([min([v for v, r in zip(s.eigenvalues, s.rigid) if not r > RIGID],
                               default=np.nan) for s in spectra]),
        time_modes=sum(s.time for s in spectra))
    return spectra


_solve_count = itertools.count(1)


def _text(value):
    """An options-database value of a Python one."""
    if value is None or value is True:
        return 'true' if value else ''
    if value is False:
        return 'false'
    if isinstance(value, (tuple, list)):
        return ','.join(format(v, 'g') if isinstance(v, float) else str(v) for v in value)
    return str(value)


@contextmanager
def _options(given, prefix):
    """The solve's options under its prefix in PETSc's database, removed after
    (a value the database held before is restored). Yields the prefix and the
    keys inserted."""
    PETSc = petsc()
    db = PETSc.Options()
    saved = {}
    try:
        for key, value in (given or {}).items():
            full = prefix + key.lstrip('-')
            if full not in saved:
                saved[full] = db.getString(full) if db.hasName(full) else None
            db.setValue(full, _text(value))
        yield saved
    finally:
        for full, old in saved.items():
            if old is None:
                db.delValue(full)
            else:
                db.setValue(full, old)


def _start_phi(scene, grid, eps, start, shape='auto'):
    """Nodal phi of the start at every node (the scene's initial `shape`, the
    -pf_start choice, or `start`'s phi_h on this grid, its tanh profile
    rescaled to `eps`), the start's multipliers (None for a fresh start) and
    whether it was solved."""
    if start is None:
        kind, geometry = appoptions.check_fits(scene, eps, shape)
        if kind != 'sharp':
            return _fresh_phi(grid.nodes, kind, geometry, scene.zc, eps), None, False
        sharp = _sharp_shape(scene)
        kind, geometry = appoptions.check_fits(scene, eps, shape, (sharp.r, sharp.z))
        # The sharp shape's multipliers are the phase field's in the limit eps -> 0: a
        # better start for stage 1 than a least-squares fit, which takes a stomatocyte's
        # inner bud into its outer membrane (nu_A ~ 245 for 1.3 at v = 0.62, eps 0.02).
        nu = np.array([sharp.tension, sharp.pressure, 0.0][:2 if grid.symmetric else 3])
        return _fresh_phi(grid.nodes, kind, geometry, scene.zc, eps), nu, True
    if start.attrs.get('symmetric', 0) != grid.symmetric:
        raise appoptions.UsageError(
            f"the start {start.path or ''} holds a "
            f"{'half' if start.attrs.get('symmetric', 0) else 'full'}-box solution: "
            f"{'add' if start.attrs.get('symmetric', 0) else 'remove'} -pf_symmetric "
            "to continue it")
    if grid._transferred is not None and grid._transferred[0] is start:
        phi = grid._transferred[1]
    elif len(start.nodes) == grid.n_nodes and np.array_equal(start.nodes, grid.nodes):
        phi = start.phi
    else:
        phi = adaptivity.transfer(start.nodes, start.phi, start.locality(grid.plane),
                                  start.basis['cutoff'], grid.nodes, grid.box, grid.plane)
    return initial.rescaled_phi(phi, start.eps, eps), start.nu, start.converged


def _sharp_shape(scene):
    """The scene's sharp-interface shape, its curve about its centroid
    (computed once per process: `analysis.limit.reference`)."""
    from pfmembrane.analysis.limit import reference
    try:
        return reference(scene.branch, scene.reduced_volume, scene.c0, scene.radius, scene.k)
    except RuntimeError as e:
        raise appoptions.UsageError(f"-pf_start sharp: no sharp-interface {scene.branch} "
                                    f"shape for v = {scene.reduced_volume:g}, C0 = "
                                    f"{scene.c0:g} ({e})") from None


def _fresh_phi(points, kind, geometry, zc, eps):
    """phi at `points` of a fresh start of `kind` (`io.options.check_fits`)."""
    if kind == 'spheroid':
        return initial.spheroid_phi(points, *geometry, zc, eps)
    if kind == 'torus':
        return initial.profile(initial.torus_distance(points, *geometry, zc), eps)
    if kind == 'spheres':
        return initial.profile(initial.spheres_distance(points, *geometry, zc), eps)
    r, z = geometry  # the sharp curve about its centroid: placed at zc, where M = 0 holds it
    return initial.profile(initial.curve_distance(points, r, z + zc, CURVE_SPACING * eps), eps)


def solve(scene, grid, eps, start=None, options=None, prefix=None, checks=True):
    """The equilibrium shape of `scene` on `grid` at width `eps`. Collective.

    Starts from the scene's initial shape (option `pf_start`,
    `io.options.STARTS`), or from `start` (a `Result`: on this grid, read from
    a file, or the parent of an adapted grid). `options` maps
    command-line names without the dash to values, PETSc's (`stage2_snes_monitor`,
    `stage1_tao_type`) and the solver's own (`pf_stage1`, `pf_mu`,
    `pf_stage1_rtol`, `pf_stage1_max_it`, `pf_stage2_rtol`, `pf_monitor`,
    `pf_force`, `pf_start`); they live under the solve's options `prefix` (by default one
    of its own, so `-PREFIX...` on the command line reaches only this solve)
    and leave the database as they found it. `checks` compares the converged
    field with the sharp-interface shape (`analysis.limit.compare`).

    Returns a `Result`; one that did not converge has `converged` False and
    the reason in `message`. Raises `io.options.UsageError` for bad input.
    """
    from pfmembrane.parallel.assembly import Problem
    from pfmembrane.parallel.faults import Interrupted
    from pfmembrane.parallel.solver import Solver, SolveError
    PETSc = petsc()
    if not grid.fits(scene):
        raise appoptions.UsageError(
            f"the scene (box {scene.box}, {'half' if scene.symmetric else 'full'} box) "
            f"does not fit the grid (box {grid.box}, {'half' if grid.symmetric else 'full'} box)")
    if not (math.isfinite(eps) and eps > 0):
        raise appoptions.UsageError(f"-pf_eps must be > 0 (got {eps!r})")
    prefix = f"pf{next(_solve_count)}_" if prefix is None else prefix
    comm, lay = grid.comm, grid.discrete.layout
    t0 = time.perf_counter()
    with _options(options, prefix) as inserted:
        settings = appoptions.read_settings(PETSc.Options(), prefix)
        under = eps < grid.eps_min
        if under and not settings.force:
            raise appoptions.UsageError(
                f"eps {eps:g} is below what this grid resolves (eps_min = {grid.eps_min:.4g}); "
                "use more nodes, an adapted grid, or -pf_force to run anyway")
        phi0, nu0, solved = _start_phi(scene, grid, eps, start, settings.start)
        problem = Problem(grid.discrete, eps, scene.k, scene.c0, (scene.area, scene.volume),
                          scene.zc)
        x = problem.create_vec()
        x.setArray(phi0[lay.order[lay.start:lay.start + lay.nowned]])
        solver = Solver(problem, settings, prefix)
        # Failures of the solve end in `state`; anything else propagates at once,
        # with no collective cleanup that a rank still computing would never reach.
        state = _run_stages(problem, solver, x, settings, nu0, solved,
                            (SolveError, Interrupted))
        phi = grid.discrete.layout.nodal(x, -1.0)
        max_phi = problem.max_abs_phi(x)
        solver.destroy()
        for key in solver.defaults:
            PETSc.Options().delValue(key)
        left = _unused(inserted, comm)
    if left:
        warnings.warn(f"solve options never used: {', '.join('-' + k for k in left)}",
                      stacklevel=2)
    mpi = comm.tompi4py()
    converged, message, status, vals, stages = state
    setup = grid.setup_time if grid._setup_pending else 0.0
    adapt_f, adapt_band, adapt_time = (
        (grid.adapt_info['f'], grid.adapt_info['band'], grid.adapt_info['time'])
        if grid._setup_pending and grid.adapt_info else (0.0, 0.0, np.nan))
    grid._setup_pending = False
    nu = solver.nu
    attrs = dict(energy=vals[0], area=vals[1], volume=vals[2], moment=vals[3], eps=eps,
                 k=scene.k, c0=scene.c0, gamma=grid.params['gamma'], nu_area=nu[0],
                 nu_volume=nu[1], nu_moment=nu[2] if solver.ncon == 3 else 0.0,
                 symmetric=int(scene.symmetric), converged=int(converged),
                 wall_time=setup + time.perf_counter() - t0, n_procs=comm.getSize(),
                 cutoff=grid.params['cutoff'], quad_degree=grid.params['quad_degree'],
                 spacing_smoothing=grid.params['spacing_smoothing'],
                 spacing_floor=grid.params['spacing_floor'], radius=scene.radius,
                 reduced_volume=scene.reduced_volume, branch=scene.branch,
                 under_resolved=int(under), eps_min=grid.eps_min, n_nodes=grid.n_nodes,
                 max_phi=max_phi,
                 stage1_iterations=solver.stats.get('stage1', {}).get('inner', -1),
                 stage2_iterations=solver.stats.get('stage2', {}).get('iterations', -1),
                 factorizations=solver.factorizations, adapt=adapt_f, adapt_band=adapt_band,
                 parent=start.path if start is not None else '',
                 start_topology=start.attrs.get('topology', '') if start is not None else '',
                 time_setup=setup, time_adapt=adapt_time,
                 time_stage1=solver.stats.get('stage1', {}).get('time', np.nan),
                 time_stage2=solver.stats.get('stage2', {}).get('time', np.nan),
                 time_assembly=_event_seconds(mpi, ASSEMBLY_EVENTS, stages),
                 time_linear=_event_seconds(mpi, LINEAR_EVENTS, stages),
                 peak_rss_mb=mpi.allreduce(
                     resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, op=_max()),
                 box=np.asarray(scene.box))
    if converged and checks:  # an interrupted run checkpoints at once
        attrs.update(phase_field_checks(mpi, grid.nodes, phi, attrs))
    return Result(grid.nodes, phi, attrs, grid=grid, message=message, status=status)


def _max():
    from mpi4py import MPI
    return MPI.MAX


def _run_stages(problem, solver, x, settings, nu0, solved, failures):
    """Stage 1 then stage 2 (or stage 2 first with -pf_stage1 none), each a
    PETSc log stage with a one-line summary. A solved start's multipliers
    `nu0` start stage 1 better than a least-squares fit; stage 2 first starts
    from the start's multipliers, solved or not. Returns (converged, message,
    status, (E, A, V, M), the log stages)."""
    PETSc = petsc()
    solved_nu = nu0 if solved else None
    stages = [('pfStage1', lambda v: solver.stage1(v, solved_nu)), ('pfStage2', solver.stage2)]
    if settings.stage1 == 'none':
        stages = [('pfStage2', lambda v: solver.stage2_first(v, solved_nu))]
        if nu0 is None:
            solver.evaluate(x)
            solver.nu = solver.least_squares_multipliers()
        else:
            solver.nu = np.asarray(nu0, dtype=float)
    logged = []
    try:
        for name, fn in stages:
            stage = PETSc.Log.Stage(name)
            logged.append(stage)
            stage.push()
            try:
                vals, _ = fn(x)
            finally:
                stage.pop()
            s = solver.stats[name[2:].lower()]
            PETSc.Sys.Print(
                f"{name[2:].lower()}: {s.get('outer', s.get('iterations'))} its"
                f"{' (' + str(s['inner']) + ' inner)' if 'inner' in s else ''}, E {s['energy']:.8f}, "
                f"constraint residual {s['residual']:.2e}, max|phi| {problem.max_abs_phi(x):.4f}, "
                f"{s['time']:.2f} s", comm=problem.comm)
    except failures as e:
        status = getattr(e, 'status', 1)
        return False, str(e), status, problem.gradients(x, solver.gE, solver.gA), logged
    return True, '', 0, vals, logged


def _unused(inserted, comm):
    """The solve's options that no rank looked up."""
    if not inserted:
        return []
    mine = set(appoptions.options_left()) & {k.lower() for k in inserted}
    return sorted(set.intersection(*map(set, comm.tompi4py().allgather(sorted(mine)))))


def _event_seconds(mpi, names, stages):
    """Seconds spent in the named log events during the stages, max over ranks."""
    PETSc = petsc()
    mine = sum(PETSc.Log.Event(name).getPerfInfo(s.id)['time'] for name in names for s in stages)
    return mpi.allreduce(mine, op=_max())


def phase_field_checks(mpi, xy, phi, attrs, keep=None):
    """phi_h one eps inside the box (`limit.boundary_phi`) and, where a level
    set exists, its topology (`limit.topology`: ``topology``, ``components``,
    ``genus``) and, for one sphere, the level set's own energy
    (`limit.level_set_energy`) and, where the scene has a sharp-interface
    shape, the energy error and level-set distance against it, or for one
    torus its own energy and radii (`limit.loop_energy`), as attributes.
    Rank 0 computes. `keep`, a dict, carries the basis's locality from one
    call to the next on the same nodes (a continuation's points)."""
    from pfmembrane.analysis import limit
    result = {}
    if mpi.Get_rank() == 0:
        ckpt = checkpoint.Checkpoint(nodes=xy, phi=phi, attrs=attrs).unfolded()
        keep = {} if keep is None else keep
        field_h = limit.PhaseField(ckpt, keep.get('beta'))
        keep['beta'] = field_h.beta
        result['boundary_phi'] = limit.boundary_phi(ckpt, field=field_h)
        try:
            curve = limit.level_set(ckpt, field=field_h)
            shape = limit.topology(curve, ckpt.box)
            result.update(topology=shape['label'], components=shape['components'],
                          genus=shape['tori'])
            if shape['label'] == '1 torus':   # no sharp torus to compare: its own energy
                energy, radii = limit.loop_energy(ckpt, curve[0], field_h)
                result.update(level_set_energy=energy, torus_radii=np.asarray(radii))
            else:
                try:
                    c = limit.compare(ckpt, field=field_h, curve=curve)
                except (ValueError, RuntimeError):
                    if shape['label'] == '1 sphere':  # no sharp shape of the scene (a pear)
                        result['level_set_energy'] = limit.level_set_energy(ckpt, curve,
                                                                            field_h)[0]
                    raise
                result.update(sharp_energy=c['energy_sharp'], sharp_rel_error=c['rel_error'],
                              sharp_dist_max=c['dist_max'], sharp_dist_mean=c['dist_mean'],
                              level_set_energy=c['energy_level_set'])
        except (ValueError, RuntimeError) as e:
            print(f"sharp interface: no comparison ({e})", flush=True)
    return mpi.bcast(result, root=0)
