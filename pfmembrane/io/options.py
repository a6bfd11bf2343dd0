"""The one place that reads, documents and validates the application options.

Everything else receives a plain `Params`. Options use the prefix `pf_`;
solver options keep PETSc's names under the prefixes `stage1_` and `stage2_`.
A `-pf_` name that `Params` does not know is refused before any work; any
other option still unused when a run has finished is refused at the end
(`check_unused`), unless `-options_left` asks for PETSc's own report.
"""
from dataclasses import dataclass, fields
import difflib
import math
import os
import tempfile


from pfmembrane.paper import PAPER_BOX, SCENE

# The initial shapes of each family (-pf_start), its default (auto) first: spheroids and
# sharp-interface shapes (`analysis.sharp`) where they exist, else a construction of its own
# (`kernels.initial.construction`; the sharp solver has no pear branch: two unequal spheres).
STARTS = {'oblate': ('spheroid', 'sharp'), 'prolate': ('spheroid', 'sharp', 'across'),
          'stomatocyte': ('sharp',), 'pear': ('spheres',), 'budded': ('spheres',),
          'torus': ('torus', 'moebius')}
BRANCHES = tuple(STARTS)
START = ('auto', 'spheroid', 'sharp', 'across', 'moebius')
# Starts built in 3D, projected onto the harmonics: only with harmonics.
STARTS_3D = ('across', 'moebius')
# Families whose starts are up-down symmetric: the half box (-pf_symmetric) holds them.
UP_DOWN = ('oblate', 'prolate', 'budded', 'torus')
SHAPE_NAMES = {'spheroid': 'spheroid', 'torus': 'ring torus', 'spheres': 'pair of spheres',
               'sharp': 'sharp-interface shape', 'across': 'spheroid across the axis',
               'moebius': 'Moebius image of the Clifford torus'}
STAGE1 = ('newton', 'tao', 'none')
HESSIANS = ('block', 'coupled')
PUSHES = ('curved', 'straight')
QUADRATURE = (1, 2, 4, 5)
MIN_NODES = 200


class UsageError(Exception):
    """Invalid input: reported as one line on stderr, exit status 2."""


@dataclass
class Settings:
    """The solver's own options: what a solve may change without a new scene
    or grid (on the command line `-pf_NAME`, in the API its options prefix)."""
    stage1: str = 'newton'
    mu: float = 0.0
    stage1_rtol: float = 1e-3
    stage1_max_it: int = 30
    stage2_rtol: float = 1e-10
    monitor: bool = False
    summary: bool = False
    path: bool = False
    force: bool = False
    start: str = 'auto'
    perturb: float = 0.02
    push: str = 'curved'
    hessian: str = 'block'
    refresh: float = 2.0


def targets(radius, reduced_volume):
    """(A0, V0) = (4 pi R^2, v 4/3 pi R^3): the area and volume a scene fixes."""
    return 4.0 * math.pi * radius ** 2, reduced_volume * 4.0 / 3.0 * math.pi * radius ** 3


class Targets:
    """The area and volume a scene (with `radius` and `reduced_volume`) fixes."""

    @property
    def area(self):
        return targets(self.radius, self.reduced_volume)[0]

    @property
    def volume(self):
        return targets(self.radius, self.reduced_volume)[1]


@dataclass
class Params(Settings, Targets):
    """Every application option: the scene, its grid, the run and the solver."""
    eps: float = 0.04
    k: float = SCENE['k']
    c0: float = SCENE['c0']
    radius: float = SCENE['radius']
    reduced_volume: float = SCENE['reduced_volume']
    box: tuple = SCENE['box']
    branch: str = SCENE['branch']
    nodes: int = 6124
    symmetric: bool = False
    gamma: float = 0.8
    restart: str = ''
    adapt: float = 0.0
    adapt_band: float = 0.0
    output: str = ''
    cutoff: float = 1e-6
    quad_degree: int = 4
    spacing_smoothing: int = 3
    spacing_floor: float = 0.0
    partition: str = 'bisection'
    modes: int = -1
    tol: float = 0.0
    tol_nodes: int = 200000
    tol_time: float = 1800.0
    harmonics: int = 0
    dihedral: int = 1
    mirror: bool = True


HELP = {
    'eps': 'regularization width eps',
    'k': 'bending rigidity',
    'c0': 'spontaneous curvature C0',
    'radius': 'radius R of the sphere of equal area: A0 = 4 pi R^2',
    'reduced_volume': 'reduced volume v: V0 = v (4/3) pi R^3, 0 < v <= 1',
    'box': 'Rb,Zb of the (r,z) box, or auto: the sharp shape and constructed start of '
           '(radius, reduced_volume, branch) with 7 eps to spare (a restart: its box)',
    'branch': 'family of the initial guess: ' + ' | '.join(BRANCHES),
    'start': 'initial shape: ' + ' | '.join(START) + ' (auto: spheroid for oblate, prolate; '
             'sharp-interface shape for stomatocyte; two spheres for budded, pear (unequal); '
             'a circular torus for torus, with the harmonic m = 1 on the half box the Moebius '
             'image where one has the reduced volume, 0.7116 to 0.98); with harmonics also '
             'across (a prolate across the axis) and moebius (a torus: the Clifford torus '
             'inverted to the reduced volume)',
    'nodes': 'approximate node count of the uniform grid (of the full box)',
    'symmetric': 'up-down symmetric scene: solve on the half box z >= Zb/2, mirror plane z = Zb/2, '
                 'no moment constraint (' + ', '.join(UP_DOWN) + ')',
    'gamma': 'max-ent locality gamma (beta_a = gamma / h_a^2)',
    'restart': 'checkpoint to start from (its nodes and phi)',
    'adapt': 'CVT density amplification f: adapt the nodes to the start phi (0: no)',
    'adapt_band': 'width w: the CVT density takes the largest |grad phi_h| within w, so the '
                  'nodes are evenly spaced across the interface (0: none)',
    'output': 'checkpoint path (default runs/<branch>_eps<eps>.h5)',
    'cutoff': 'max-ent support cut-off: node a is used where exp(-beta_a d^2) >= cutoff',
    'quad_degree': 'Gauss rule degree on the Delaunay triangles: 1 | 2 | 4 | 5',
    'spacing_smoothing': 'smoothing passes over the nodal spacing h_a behind beta_a (0: raw h_a)',
    'spacing_floor': 'quantile Q of the smoothed h_a below which beta_a stays gamma / h_Q^2: one '
                     'locality over the finest nodes of a graded grid (0: none)',
    'partition': 'nodes among the ranks: bisection (coordinate; the same in every run) | '
                 'a MatPartitioning type (ptscotch: graph, changes from run to run)',
    'modes': 'stability of the converged shape against psi(r,z) cos(m theta), m = 0..M: the '
             'index per m (-1: none; eigensolver options -modes_eps_...)',
    'tol': 'accuracy on demand: solves from -pf_eps down in eps on grids that resolve it until '
           'the sharp-limit estimate (the level set\'s energy) is within TOL relative by its '
           'error bar (pfmembrane.accuracy; steps in <output stem>_tol/, resumed; 0: off)',
    'tol_nodes': 'with -pf_tol: the most nodes of any grid (the budget)',
    'tol_time': 'with -pf_tol: the wall seconds of the run (the budget)',
    'harmonics': 'J: phi carries the azimuthal harmonics m = j n, j = 0..J (n: -pf_dihedral), '
                 'psi_j = r^m chi_j(r,z) cos(m theta); 0: axisymmetric',
    'dihedral': 'dihedral order n of the scene: the harmonics are multiples of n',
    'mirror': 'a mirror plane through the axis: cosines only (0: sines too, with -pf_dihedral '
              '>= 2 on the full box; a phase condition holds the rotation about the axis)',
    'perturb': 'with harmonics: largest |psi_m| of the push a fresh start gets along the '
               'critical mode of each harmonic m unstable at the solved axisymmetric state '
               '(an axisymmetric restart: a deterministic bump in every m > 0)',
    'push': 'with harmonics, a fresh start pushed along one critical mode: curved (along '
            'the centre manifold to second order, to the amplitude where its reduced energy '
            'alpha t^2 + beta t^4 is least; straight where beta <= 0) | straight (by '
            '-pf_perturb)',
    'hessian': 'with harmonics, the Hessian the solver factors: block (the mode Hessians of the '
               'theta-averaged state: the preconditioner of GMRES on the exact action) | coupled '
               '(the exact one, every pair of harmonics: nh^2 times the entries, direct solves '
               'whose inertia is exact)',
    'refresh': 'with harmonics and the block Hessian: a Newton step keeps the factored '
               'preconditioner diag(H_m) until a Krylov solve needs more than REFRESH times the '
               'iterations of the first solve on it (0: a new one at every step)',
    'stage1': 'augmented-Lagrangian inner solver: newton | tao (-stage1_tao_type) | none (restarts)',
    'mu': 'initial penalty mu of the augmented Lagrangian (0: 1e-5 newton, 1e-4 tao)',
    'stage1_rtol': 'relative constraint residual that ends stage 1',
    'stage1_max_it': 'augmented-Lagrangian outer iterations',
    'stage2_rtol': 'relative residual of the bordered Newton stage',
    'monitor': 'print one row per iteration (energy, residuals, max |phi|)',
    'summary': 'print one line per stage (the command line: always; the API: when asked)',
    'path': 'record the energy path on the constraints: E of every iterate of both stages '
            'put back on the area, volume and moments (result attribute energy_path; the '
            'summary says where it rises)',
    'force': 'run even when eps is below what the grid resolves (result flagged)',
}

# bisection (`parallel.partition`) and the graph partitioners PETSc may be built with
PARTITIONS = ('bisection', 'ptscotch', 'parmetis', 'chaco', 'party')

KINDS = {float: 'a number', int: 'an integer', bool: 'true or false',
         tuple: "two numbers Rb,Zb or 'auto'"}


def help_text():
    """The application options with their defaults."""
    lines = ['pfmembrane: equilibrium vesicle shapes, phase field on local max-ent approximants',
             'Application options (PETSc solver options go under -stage1_ and -stage2_):']
    solver = {f.name for f in fields(Settings)}
    for f in sorted(fields(Params), key=lambda f: f.name in solver):  # the scene first
        default = f.default
        if f.name == 'box':
            default = ','.join(format(b, 'g') for b in PAPER_BOX)
        lines.append(f"  -pf_{f.name:<16s} {str(default) or 'none':<10s} {HELP[f.name]}")
    lines += ['Options nothing used are errors (-options_left: warnings).',
              'Exit status: 0 converged; 1 not converged; 2 invalid input; 3 PETSc error;',
              '4 aborted; 128+N stopped by signal N (SIGTERM, SIGINT). With 1 and 128+N the',
              'checkpoint of the last iterate is still written, marked converged = 0.']
    return '\n'.join(lines)


def _get(opts, name, kind, default, prefix=''):
    key = prefix + 'pf_' + name
    if not opts.hasName(key):
        return default
    text = opts.getString(key, '') or ''
    try:
        if kind is bool:
            if text.lower() in ('', 'true', '1', 'yes', 'on'):
                return True
            if text.lower() in ('false', '0', 'no', 'off'):
                return False
            raise ValueError
        if kind is str:
            if not text:
                raise UsageError(f"-{key} needs a value")
            return text
        if kind is tuple:
            if text.strip().lower() == 'auto':
                return 'auto'
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
        raise UsageError(f"-{key}: cannot read {text!r} as {KINDS[kind]}") from None


class Table(dict):
    """Options of options files in PETSc's format (`-name [value]`, `#`
    comments), later ones overriding earlier ones, behind the part of
    petsc4py's Options interface that `read` uses: the drivers read step
    files with it without touching the global database."""

    @classmethod
    def from_files(cls, *paths, args=()):
        table = cls()
        for path in paths:
            try:
                with open(path) as f:
                    text = f.read()
            except OSError as e:
                raise UsageError(f"cannot read options file {path}: {e.strerror}") from None
            table._insert(' '.join(line.split('#', 1)[0] for line in text.splitlines()).split())
        table._insert(list(args))
        return table

    def _insert(self, tokens):
        name = None
        for token in tokens:
            if token.startswith('-') and len(token) > 1 and not _is_number(token):
                name = token[1:].lower()
                self[name] = ''
            elif name is not None:
                self[name] = token if not self[name] else self[name] + ' ' + token
            else:
                raise UsageError(f"options: value {token!r} follows no option name")

    def hasName(self, name):
        return name.lower() in self

    def getString(self, name, default=None):
        return self.get(name.lower(), default)

    def getAll(self):
        return dict(self)


def _is_number(token):
    try:
        float(token)
        return True
    except ValueError:
        return False


def check_names(opts, prefix='', record=Params):
    """Refuse a `-PREFIXpf_` option that `record` does not know: a typo must
    fail before the expensive work, not at the end of the run."""
    start = (prefix + 'pf_').lower()
    known = [start + f.name for f in fields(record)]
    for name in sorted(opts.getAll()):
        # PETSc matches option names without regard to case.
        if name.lower().startswith(start) and name.lower() not in known:
            guess = difflib.get_close_matches(name.lower(), known, n=1)
            hint = f" (did you mean -{guess[0]}?)" if guess else ''
            raise UsageError(f"unknown option {'-' + name!r}{hint}; -help lists the options")


def read(opts):
    """Params from a petsc4py Options database, validated."""
    check_names(opts)
    values = {f.name: _get(opts, f.name, type(f.default), f.default) for f in fields(Params)}
    p = Params(**values)
    validate(p)
    return p


def read_settings(opts, prefix=''):
    """The solver `Settings` under an options prefix, validated. Without a
    prefix the names are the application's (`read` checks them)."""
    if prefix:
        check_names(opts, prefix, Settings)
    s = Settings(**{f.name: _get(opts, f.name, type(f.default), f.default, prefix)
                    for f in fields(Settings)})
    validate_settings(s, prefix)
    return s


def _require(ok, name, what, value, prefix=''):
    if not ok:
        raise UsageError(f"-{prefix}pf_{name} must be {what} (got {value!r})")


def validate_settings(s, prefix=''):
    """Raise UsageError with one line naming the option for a bad solver setting."""
    for f in fields(Settings):
        if f.type is float:
            _require(math.isfinite(getattr(s, f.name)), f.name, 'a finite number',
                     getattr(s, f.name), prefix)
    if s.start not in START:
        raise UsageError(f"-{prefix}pf_start: unknown start {s.start!r} (choose {', '.join(START)})")
    if s.hessian not in HESSIANS:
        raise UsageError(f"-{prefix}pf_hessian: unknown Hessian {s.hessian!r} "
                         f"(choose {', '.join(HESSIANS)})")
    if s.push not in PUSHES:
        raise UsageError(f"-{prefix}pf_push: unknown push {s.push!r} "
                         f"(choose {', '.join(PUSHES)})")
    if s.stage1 not in STAGE1:
        raise UsageError(f"-{prefix}pf_stage1: unknown solver {s.stage1!r} "
                         f"(choose {', '.join(STAGE1)})")
    for name in ('stage1_rtol', 'stage2_rtol'):
        _require(0.0 < getattr(s, name) < 1.0, name, 'in (0, 1)', getattr(s, name), prefix)
    _require(s.mu >= 0, 'mu', '>= 0', s.mu, prefix)
    _require(s.refresh >= 0, 'refresh', '>= 0', s.refresh, prefix)
    _require(s.stage1_max_it >= 1, 'stage1_max_it', '>= 1', s.stage1_max_it, prefix)


def check_scene(s):
    """Raise UsageError for an impossible scene (of `Params` or `api.Scene`)."""
    for name in ('k', 'c0', 'radius', 'reduced_volume'):
        _require(math.isfinite(getattr(s, name)), name, 'a finite number', getattr(s, name))
    if s.box != 'auto':
        _require(len(s.box) == 2 and all(math.isfinite(b) and b > 0 for b in s.box),
                 'box', 'two positive numbers Rb,Zb', s.box)
    for name in ('k', 'radius'):
        _require(getattr(s, name) > 0, name, '> 0', getattr(s, name))
    if not 0.0 < s.reduced_volume <= 1.0:
        raise UsageError(f"-pf_reduced_volume must lie in (0, 1] (got {s.reduced_volume!r}): "
                         "no closed surface encloses more than the sphere of the same area")
    if s.branch not in BRANCHES:
        raise UsageError(f"-pf_branch: unknown shape {s.branch!r} (choose {', '.join(BRANCHES)})")
    harmonics, dihedral = getattr(s, 'harmonics', 0), getattr(s, 'dihedral', 1)
    _require(harmonics >= 0, 'harmonics', '>= 0', harmonics)
    _require(dihedral >= 1, 'dihedral', '>= 1', dihedral)
    if harmonics and dihedral == 1 and not s.symmetric:
        raise UsageError("-pf_harmonics with -pf_dihedral 1 on the full box: m = 1 holds the "
                         "rotations about axes across the axis, which only the half box's "
                         "mirror pins (add -pf_symmetric), or give the scene's dihedral order "
                         "n >= 2")
    if harmonics and not getattr(s, 'mirror', True) and (dihedral == 1 or s.symmetric):
        raise UsageError("-pf_mirror 0: sines (no mirror plane through the axis) need "
                         "-pf_dihedral n >= 2 (the sine m = 1 holds the translation along y, "
                         "which nothing pins) and the full box")
    if s.symmetric and s.branch not in UP_DOWN:
        raise UsageError(f"-pf_symmetric: the {s.branch} is not up-down symmetric, the half box "
                         f"cannot hold it (the half box admits {', '.join(UP_DOWN)})")


def validate(p):
    """Raise UsageError with one line naming the option for any inconsistent
    setting. A fresh start's box `auto` is left for the caller to size
    (`analysis.sizing.auto_box`) and check (`check_fits`)."""
    for f in fields(Params):
        value = getattr(p, f.name)
        if f.type is float:
            _require(math.isfinite(value), f.name, 'a finite number', value)
    check_scene(p)
    for name in ('eps', 'gamma'):
        _require(getattr(p, name) > 0, name, '> 0', getattr(p, name))
    if p.tol and p.harmonics:
        raise UsageError("-pf_tol with -pf_harmonics: accuracy on demand is axisymmetric only")
    validate_settings(p)
    _require(p.quad_degree in QUADRATURE, 'quad_degree', f"one of {QUADRATURE}", p.quad_degree)
    _require(0.0 < p.cutoff < 1.0, 'cutoff', 'in (0, 1)', p.cutoff)
    _require(p.adapt >= 0, 'adapt', '>= 0', p.adapt)
    if p.adapt and not p.restart:
        raise UsageError("-pf_adapt needs -pf_restart: the nodes are adapted to a solved phi")
    _require(p.adapt_band >= 0, 'adapt_band', '>= 0', p.adapt_band)
    if p.adapt_band and not p.adapt:
        raise UsageError("-pf_adapt_band needs -pf_adapt: it shapes the CVT density")
    _require(0 <= p.spacing_smoothing <= 100, 'spacing_smoothing', 'in 0..100', p.spacing_smoothing)
    _require(0.0 <= p.spacing_floor < 1.0, 'spacing_floor', 'in [0, 1)', p.spacing_floor)
    _require(-1 <= p.modes <= 50, 'modes', 'in -1..50', p.modes)
    _require(0.0 <= p.tol < 1.0, 'tol', 'in [0, 1)', p.tol)
    _require(p.tol_nodes >= MIN_NODES, 'tol_nodes', f'>= {MIN_NODES}', p.tol_nodes)
    _require(p.tol_time > 0, 'tol_time', '> 0', p.tol_time)
    if p.tol and p.restart:
        raise UsageError("-pf_tol starts from the scene, not -pf_restart: a rerun with the "
                         "same -pf_output resumes from its steps (<output stem>_tol/)")
    if p.tol and p.modes >= 0:
        raise UsageError("-pf_modes with -pf_tol: analyse the checkpoint it writes instead "
                         "(-pf_restart CKPT -pf_stage1 none -pf_modes M)")
    _require(p.partition in PARTITIONS, 'partition', f"one of {', '.join(PARTITIONS)}",
             p.partition)
    if p.nodes < MIN_NODES and not p.restart:
        raise UsageError(f"-pf_nodes {p.nodes} is too few: at least {MIN_NODES} nodes are needed")
    if not p.restart:
        start_kind(p.branch, p.start)  # whether its start fits its box: `starts.check_fits`


def start_kind(branch, start='auto'):
    """The initial shape of the family `branch` that -pf_start `start` asks for."""
    if start == 'auto':
        return STARTS[branch][0]
    if start not in STARTS[branch]:
        raise UsageError(f"-pf_start {start}: the {branch} starts from "
                         f"{' or '.join(STARTS[branch])} (-pf_start auto)")
    return start


def default_output(p):
    return f"runs/{p.branch}_eps{p.eps:g}.h5"


def check_output(path, comm):
    """Refuse, before any work, a checkpoint path that cannot be written.

    Collective: rank 0, the rank that writes checkpoints, decides for all.

    Parameters
    ----------
    path : str
        Checkpoint path; missing directories are created when it is written.
    comm : mpi4py.MPI.Comm
    """
    problem = _output_problem(path) if comm.Get_rank() == 0 else None
    problem = comm.bcast(problem, root=0)
    if problem:
        raise UsageError(f"-pf_output {path!r}: {problem}")


def _output_problem(path):
    target = os.path.abspath(path)
    if os.path.isdir(target):
        return "is a directory"
    parent = os.path.dirname(target)
    while not os.path.lexists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        return f"{parent!r} is not a directory"
    # Permission bits do not tell (root, read-only mounts): try to create a file.
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix='.pfmembrane-probe-')
    except OSError as e:
        return f"cannot create files in {parent!r} ({e.strerror})"
    os.close(fd)
    os.remove(probe)
    return None


def check_unused(opts, comm, given, left):
    """Refuse options given to a finished run that nothing used.

    Collective. The PETSc database marks every option looked up; those of
    `given` (the names present at start-up) that no rank looked up are
    misspelt, or meant for a solver this run does not create. With `-help`
    nothing was meant to be used; with `-options_left` PETSc reports them
    itself when it finalizes.

    Parameters
    ----------
    opts : petsc4py.PETSc.Options
        The global database.
    comm : mpi4py.MPI.Comm
    given : iterable of str
        Option names (without the dash) present before the run.
    left : iterable of str
        The names nothing looked up (`parallel.petsc.options_left`).
    """
    if opts.hasName('help') or opts.hasName('options_left'):
        return
    mine = set(left) & {name.lower() for name in given}
    unused = sorted(set.intersection(*map(set, comm.allgather(sorted(mine)))))
    if unused:
        raise UsageError(
            f"option{'s' if len(unused) > 1 else ''} {', '.join('-' + n for n in unused)} "
            "never used (misspelt, or for a solver this run does not create); "
            "-options_left reports them without failing")
