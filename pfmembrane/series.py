"""Independent series of solves, for studies and for users with many scenes:
runs under mpiexec started from a script (the one place that builds an
mpiexec line and the environment it runs in), the ranks of such a run split
into groups that each take their share of the pieces, and the command-line
arguments such a study shares (`--np`, `--groups`, grids, solver options).

A script `runs/<study>/<study>.py` calls `ensure_ranks(np, __file__, argv)`
(or `on_groups`) and is restarted under `mpiexec -n NP` when it was started
without it; `module` may be a module name (`python -m MODULE`) or a script
path."""
import datetime
import functools
import os
import subprocess
import sys
import traceback
from contextlib import contextmanager


def command(nprocs, *args, module='pfmembrane'):
    """`mpiexec -n NPROCS python -m MODULE ARGS...` (or `python SCRIPT ARGS...`
    for a `module` ending in .py) with this interpreter, and the mpiexec
    installed beside it if there is one (`make install`'s)."""
    beside = os.path.join(os.path.dirname(sys.executable), 'mpiexec')
    mpiexec = beside if os.access(beside, os.X_OK) else 'mpiexec'
    target = [os.path.abspath(module)] if module.endswith('.py') else ['-m', module]
    return [mpiexec, '-n', str(nprocs), sys.executable, *target, *args]


def environment():
    """Python's copy of the environment. Once MPI is initialised in this process
    (under pytest, or after importing PETSc for a measurement), it has added
    variables to the C environment that make a child mpiexec fail at once."""
    return dict(os.environ)


def run(cmd, **kwargs):
    """subprocess.run of an mpiexec line in `environment()`."""
    return subprocess.run(cmd, env=environment(), **kwargs)


def under_mpiexec():
    """Whether this process was started by mpiexec (Open MPI, or a PMI launcher
    such as MPICH's), told without initialising MPI."""
    return any(k in os.environ for k in ('OMPI_COMM_WORLD_SIZE', 'PMI_SIZE', 'PMIX_RANK'))


def ensure_ranks(nprocs, module, argv):
    """Run `python -m MODULE ARGV` under `mpiexec -n NPROCS` and exit with its
    status, unless this process already runs under mpiexec or one rank is asked."""
    if nprocs > 1 and not under_mpiexec():
        sys.exit(run(command(nprocs, *argv, module=module)).returncode)


def group_arguments(ap, piece):
    """--np and --groups of a driver whose `piece`s run on rank groups (`on_groups`),
    and the solver options after `--`."""
    ap.add_argument('--np', type=int, default=2, help='MPI ranks')
    ap.add_argument('--groups', type=int, default=1, help=f'rank groups, one {piece} each')
    ap.add_argument('options', nargs='*', metavar='-- OPTION')


def grid_arguments(ap, eps, nodes, box):
    """--eps, --nodes (the spacing of that many nodes in the paper box) and --box
    Rb,Zb (`box`: what it replaces) of a driver's grids."""
    ap.add_argument('--eps', type=float, default=eps)
    ap.add_argument('--nodes', type=int, default=nodes, help='nodes in the paper box (scaled)')
    ap.add_argument('--box', type=lambda t: tuple(map(float, t.split(','))),
                    help=f'Rb,Zb of every {box}')


def parsed(ap, argv):
    """`ap`'s arguments (`group_arguments` among them), with `solver`: the options after
    `--` as a dict of names without the dash; refuses groups that do not divide --np."""
    args = ap.parse_args(argv)
    args.solver = {k.lstrip('-'): v for k, v in zip(args.options[::2], args.options[1::2])}
    if args.groups < 1 or args.np % args.groups:
        ap.error(f"--groups {args.groups} does not divide --np {args.np}")
    return args


def on_groups(nprocs, groups, module, pieces, work):
    """`work(piece, comm, say)` for every piece, on `groups` groups of consecutive ranks
    of `nprocs` (under mpiexec, started if need be: `ensure_ranks`), group g taking the
    pieces g, g + groups, ...; `say` prints once per group, tagged with it. Returns the
    results in the order of `pieces` on the world's first rank, None on the others. A
    failure on one rank aborts them all (`all_or_none`)."""
    ensure_ranks(nprocs, module, sys.argv[1:])
    import pfmembrane as pf
    PETSc = pf.api.petsc(sys.argv[:1])
    world = PETSc.COMM_WORLD.tompi4py()
    group = world.Get_rank() * groups // world.Get_size()
    comm = PETSc.Comm(world.Split(group, world.Get_rank()))

    def say(text):
        PETSc.Sys.Print(f"[group {group}] {text}" if groups > 1 else text, comm=comm)

    with all_or_none(world):
        mine = [(i, work(pieces[i], comm, say)) for i in range(group, len(pieces), groups)]
    gathered = world.gather(mine if comm.getRank() == 0 else [], root=0)
    if world.Get_rank() != 0:
        return None
    done = dict(pair for part in gathered for pair in part)
    return [done[i] for i in range(len(pieces))]


@contextmanager
def all_or_none(world):
    """Abort every rank of `world` (mpi4py) when this one raises: a rank group whose
    work failed would leave the others waiting for it in a collective call forever."""
    try:
        yield
    except Exception:
        traceback.print_exc()
        sys.stderr.flush()
        world.Abort(1)


def seconds_left(until):
    """Seconds to `until` (HH:MM UTC), inf without it: a study's deadline, the
    first HH:MM after the study first asks (a run started at 23:20 with
    --until 01:25 has two hours, not none)."""
    if not until:
        return float('inf')
    return (_deadline(until) - datetime.datetime.now(datetime.timezone.utc)).total_seconds()


@functools.lru_cache(maxsize=None)
def _deadline(until):
    """The first HH:MM `until` UTC after now, fixed at the first call."""
    now = datetime.datetime.now(datetime.timezone.utc)
    h, m = map(int, until.split(':'))
    at = now.replace(hour=h, minute=m, second=0, microsecond=0)
    return at if at > now else at + datetime.timedelta(days=1)
