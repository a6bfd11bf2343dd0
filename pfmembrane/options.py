"""The one place that reads, documents and validates the application options.

Everything else receives a plain `Params`. Options use the prefix `pf_`;
solver options keep PETSc's names under the prefixes `stage1_` and `stage2_`.
"""
from dataclasses import dataclass, fields
import math

BRANCHES = ('oblate', 'prolate')
STAGE1 = ('newton', 'tao')
QUADRATURE = (1, 2, 4, 5)


class UsageError(Exception):
    """Invalid input: reported as one line on stderr, exit status 2."""


@dataclass
class Params:
    eps: float = 0.04
    k: float = 1.0
    c0: float = 0.0
    radius: float = 0.4
    reduced_volume: float = 0.8
    box: tuple = (1.5, 2.0)
    branch: str = 'oblate'
    nodes: int = 6124
    gamma: float = 0.8
    restart: str = ''
    adapt: float = 0.0
    output: str = ''
    cutoff: float = 1e-6
    quad_degree: int = 4
    stage1: str = 'newton'
    mu: float = 0.0
    stage1_rtol: float = 1e-3
    stage1_max_it: int = 30
    stage2_rtol: float = 1e-10
    monitor: bool = False
    force: bool = False

    @property
    def area(self):
        return 4.0 * math.pi * self.radius ** 2

    @property
    def volume(self):
        return self.reduced_volume * 4.0 / 3.0 * math.pi * self.radius ** 3

    @property
    def zc(self):
        return 0.5 * self.box[1]


HELP = {
    'eps': 'regularization width eps',
    'k': 'bending rigidity',
    'c0': 'spontaneous curvature C0',
    'radius': 'radius R of the sphere of equal area: A0 = 4 pi R^2',
    'reduced_volume': 'reduced volume v: V0 = v (4/3) pi R^3, 0 < v <= 1',
    'box': 'Rb,Zb of the (r,z) box',
    'branch': 'family of the initial guess: ' + ' | '.join(BRANCHES),
    'nodes': 'approximate node count of the uniform grid',
    'gamma': 'max-ent locality gamma (beta_a = gamma / h_a^2)',
    'restart': 'checkpoint to start from (its nodes and phi)',
    'adapt': 'CVT density amplification f: adapt the nodes to the start phi (0: no)',
    'output': 'checkpoint path (default runs/<branch>_eps<eps>.h5)',
    'cutoff': 'max-ent support cut-off: node a is used where exp(-beta_a d^2) >= cutoff',
    'quad_degree': 'Gauss rule degree on the Delaunay triangles: 1 | 2 | 4 | 5',
    'stage1': 'augmented-Lagrangian inner solver: newton (Hessian) | tao (-stage1_tao_type)',
    'mu': 'initial penalty mu of the augmented Lagrangian (0: 1e-5 newton, 1e-4 tao)',
    'stage1_rtol': 'relative constraint residual that ends stage 1',
    'stage1_max_it': 'augmented-Lagrangian outer iterations',
    'stage2_rtol': 'relative residual of the bordered Newton stage',
    'monitor': 'print one row per iteration (energy, residuals, max |phi|)',
    'force': 'run even when eps is below what the grid resolves (result flagged)',
}


def help_text():
    """The application options with their defaults."""
    lines = ['pfmembrane: equilibrium vesicle shapes, phase field on local max-ent approximants',
             'Application options (PETSc solver options go under -stage1_ and -stage2_):']
    for f in fields(Params):
        default = f.default
        if f.name == 'box':
            default = '1.5,2'
        lines.append(f"  -pf_{f.name:<16s} {str(default) or 'none':<10s} {HELP[f.name]}")
    return '\n'.join(lines)


def _get(opts, name, kind, default):
    key = 'pf_' + name
    if not opts.hasName(key):
        return default
    text = opts.getString(key, '')
    try:
        if kind is bool:
            if text.lower() in ('', 'true', '1', 'yes', 'on'):
                return True
            if text.lower() in ('false', '0', 'no', 'off'):
                return False
            raise ValueError
        if kind is tuple:
            value = tuple(float(t) for t in text.split(','))
            if len(value) != 2:
                raise ValueError
            return value
        if kind is int:
            value = float(text)  # accepts 6124 and 6.124e3, refuses 61.5
            if not value.is_integer():
                raise ValueError
            return int(value)
        return kind(text)
    except ValueError:
        raise UsageError(f"-{key}: cannot read '{text}' as {kind.__name__}") from None


def read(opts):
    """Params from a petsc4py Options database, validated."""
    values = {f.name: _get(opts, f.name, type(f.default), f.default) for f in fields(Params)}
    p = Params(**values)
    validate(p)
    return p


def validate(p):
    """Raise UsageError with one clear line for any inconsistent setting."""
    for name in ('eps', 'k', 'radius', 'gamma', 'reduced_volume', 'cutoff', 'c0', 'adapt', 'mu'):
        if not math.isfinite(getattr(p, name)):
            raise UsageError(f"-pf_{name} must be a finite number")
    if p.eps <= 0:
        raise UsageError(f"-pf_eps must be > 0 (got {p.eps:g})")
    if p.k <= 0 or p.radius <= 0 or p.gamma <= 0:
        raise UsageError("-pf_k, -pf_radius and -pf_gamma must be > 0")
    if not 0.0 < p.reduced_volume <= 1.0:
        raise UsageError(f"-pf_reduced_volume must lie in (0, 1] (got {p.reduced_volume:g}): "
                         "no closed surface encloses more than the sphere of the same area")
    if p.branch not in BRANCHES:
        raise UsageError(f"-pf_branch: unknown shape '{p.branch}' (choose {', '.join(BRANCHES)})")
    if p.stage1 not in STAGE1:
        raise UsageError(f"-pf_stage1: unknown solver '{p.stage1}' (choose {', '.join(STAGE1)})")
    if p.quad_degree not in QUADRATURE:
        raise UsageError(f"-pf_quad_degree must be one of {QUADRATURE}")
    if not 0.0 < p.cutoff < 1.0:
        raise UsageError("-pf_cutoff must lie in (0, 1)")
    if p.adapt < 0 or p.mu < 0:
        raise UsageError("-pf_adapt and -pf_mu must be >= 0")
    if not all(math.isfinite(b) and b > 0 for b in p.box):
        raise UsageError("-pf_box must be two positive numbers Rb,Zb")
    if p.nodes < 200 and not p.restart:
        raise UsageError(f"-pf_nodes {p.nodes} is too few: at least 200 nodes are needed")
    check_fits(p)


def check_fits(p):
    """The initial spheroid of the branch, with a 3 eps margin, must fit the box."""
    from .initial import spheroid_axes
    a, c = spheroid_axes(p.area, p.volume, p.branch)
    Rb, Zb = p.box
    margin = 3.0 * p.eps
    if a + margin > Rb or c + margin > 0.5 * Zb:
        raise UsageError(
            f"-pf_box {Rb:g},{Zb:g} cannot hold the {p.branch} vesicle (semi-axes a={a:.4g}, "
            f"c={c:.4g}) with a margin of 3 eps: need Rb >= {a + margin:.4g}, Zb >= {2 * (c + margin):.4g}")
    return a, c


def default_output(p):
    return f"runs/{p.branch}_eps{p.eps:g}.h5"


def stage1_penalty(p):
    return p.mu if p.mu > 0 else (1e-5 if p.stage1 == 'newton' else 1e-4)
