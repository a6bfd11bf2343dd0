"""Continuation of an equilibrium branch in the reduced volume (paper Figure 6).

    python runs/branches/branch.py --branch oblate --from 0.95 --to 0.65 --step 0.05 --out runs/branches
        [--np 2] [--eps 0.04] [--nodes 6124] [--box Rb,Zb] [--force] [-- SOLVER OPTIONS]
    python runs/branches/branch.py --plot runs/branches

The first reduced volume is solved from the spheroid initial guess of the branch; every next
one restarts from the result of the previous one (`-pf_restart PREV.h5 -pf_reduced_volume v
-pf_stage1 none`: Newton on the bordered system first, both stages should it fail), or, after
two solved volumes, from the secant through them (`api.predict`), so that the solution follows
the branch as the vesicle deflates. A step is what `python -m pfmembrane
-options_file options/branch/<branch>.opts ...` would run (`runner.run_files`), writing
OUT/<branch>/v<v>.h5, but all
steps run in one process on NP ranks (started under mpiexec if need be), on one grid built once,
each from the previous result in memory. Options after `--` are added to every run (solver
options such as `-pf_stage1_rtol 1e-5`: a checkpoint is reused whatever they were). Steps whose converged
checkpoint of the same scene, grid and start exists are not run again (unless --force); once a
step runs, the later ones run too. The branch stops at the first failed step. The table goes
to OUT/<branch>.md, headed by the provenance of the measurement (`report.provenance`).

A restart keeps the box of its checkpoint, so one box serves the whole branch: the paper's
1.5 x 2, enlarged where a shape of the branch needs it (`sizing.required_box`,
`sizing.default_box`).

`--plot OUT` draws OUT/energy.png: E against v for every branch under OUT, the sharp-interface
energies as lines, and the zero level sets of the phase fields as a strip of silhouettes.

The scene files are found from the repository root, whatever the working directory; OUT
defaults to runs/branches there.
"""
import argparse
import glob
import math
import os
import sys
import time

import h5py
import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane import series as launch
from pfmembrane.report import iterations
from pfmembrane.cli import runner
from pfmembrane.cli.runner import option_of
from pfmembrane.analysis.sizing import default_box, required_box, uniform_grid
from pfmembrane.paper import PAPER_BOX

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join('options', 'branch', '{}.opts')   # relative to ROOT
BRANCHES = ('oblate', 'prolate')   # the branches with a scene file SCENE
NAME = 'branch.py'   # the prefix of the messages

# The application requires the initial spheroid to fit the box with 3 eps to spare;
# the same margin keeps phi = -1 on the box edges away from every shape of the branch.
MARGIN = 3.0
SHARP_DV = 0.01         # v spacing of the sharp-interface line of the figure


def shown(path):
    """`path` as a page names it: relative to the repository root when inside it."""
    path = os.path.abspath(path)
    inside = os.path.commonpath([path, ROOT]) == ROOT
    return os.path.relpath(path, ROOT) if inside else path


def scene_value(scene, name):
    """The last value the options file `scene` (relative to ROOT) gives to -pf_<name>,
    as a float."""
    value = option_of(os.path.join(ROOT, scene), f'pf_{name}')
    if value is None:
        sys.exit(f"{scene}: names no -pf_{name}")
    return float(value)


def volumes(start, stop, step):
    """Reduced volumes from `start` to `stop`, both included, `step` apart.

    Raises
    ------
    ValueError
        If a volume leaves (0, 1] or `stop` is not a whole number of steps away.
    """
    if step <= 0:
        raise ValueError(f"--step must be > 0 (got {step:g})")
    count = round(abs(stop - start) / step)
    if not math.isclose(count * step, abs(stop - start), abs_tol=1e-9):
        raise ValueError(f"--to {stop:g} is not a whole number of steps {step:g} from --from {start:g}")
    vs = [round(start + math.copysign(i * step, stop - start), 10) for i in range(count + 1)]
    if not all(0.0 < v <= 1.0 for v in vs):
        raise ValueError("reduced volumes must lie in (0, 1]")
    return vs


def _attrs(path):
    try:
        with h5py.File(path, 'r') as f:
            return dict(f.attrs)
    except (OSError, KeyError):
        return None


def reusable(path, expected):
    """Whether `path` holds a converged checkpoint with the `expected` attributes
    (numbers to 1e-9, the box to 1e-12)."""
    a = _attrs(path)
    if a is None or not a.get('converged'):
        return False
    for key, value in expected.items():
        if key not in a:
            return False
        if isinstance(value, str):
            if str(a[key]) != value:
                return False
        elif not np.allclose(a[key], value, rtol=1e-9, atol=1e-12):
            return False
    return True


def run(branch, vs, box, args):
    """Solve the volumes in order, each from the checkpoint of the one before.

    Returns
    -------
    list of dict
        One per volume attempted: ``v``, ``path``, ``parent`` ('' for the
        spheroid start), ``wall`` (seconds, None if reused), ``status`` (exit
        status), ``message`` (the run's own line on stderr when it failed) and
        ``written`` (whether `path` is a checkpoint of this step).
    """
    PETSc = pf.petsc(sys.argv[:1])
    say = PETSc.Sys.Print
    scene = SCENE.format(branch)
    n_nodes, _ = uniform_grid(box, args.nodes)
    steps, parent, rerun, cache = [], '', args.force, runner.Cache()
    solved = []  # (v, result) of the steps solved here, for the secant predictor
    for v in vs:
        path = os.path.join(args.out, branch, f"v{v:g}.h5")
        step = dict(v=v, path=path, parent=parent, wall=None, status=0, message='', written=True)
        steps.append(step)
        expected = dict(branch=branch, reduced_volume=v, eps=args.eps, n_nodes=n_nodes, box=box,
                        parent=parent)
        if rerun or not reusable(path, expected):
            rerun = True
            line = ['-pf_eps', f"{args.eps:g}", '-pf_nodes', str(args.nodes),
                    '-pf_box', f"{box[0]:g},{box[1]:g}", '-pf_reduced_volume', f"{v:g}",
                    '-pf_output', path,
                    *(['-pf_restart', parent, '-pf_stage1', 'none'] if parent else []),
                    *args.options]
            say(f"-- v = {v:g}: -options_file {scene} {' '.join(line)}")
            t0 = time.time()
            predicted = None
            if len(solved) >= 2 and solved[-1][1].path == parent:
                (v0, r0), (v1, r1) = solved[-2:]
                predicted = pf.predict(r0, r1, (v - v1) / (v1 - v0))
            try:
                res, _ = runner.run_files(os.path.join(ROOT, scene), args=line,
                                          comm=PETSc.COMM_WORLD, print_fn=say, cache=cache,
                                          start=predicted)
                runner.summary(res, path, say)
                if res.converged:
                    solved.append((v, res))
                step['status'], step['message'] = res.status, res.message
            except runner.UsageError as e:
                # invalid input writes no checkpoint: a file there is an older one
                step['status'], step['message'], step['written'] = 2, f"error: {e}", False
            step['wall'] = time.time() - t0
            if step['status'] != 0:
                say(f"v = {v:g}: exit status {step['status']} ({step['message']}); "
                    "the branch stops here")
                break
        parent = path
    return steps


def table(steps):
    """Markdown rows, one per step, and the sum of the runs' wall times."""
    rows = ['| v | start | E | nu_A | nu_V | max phi | its (1+2) | converged | E_sharp | error vs sharp '
            '| d max | topology | index per m | run s | wall s |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    total = 0.0
    for step in steps:
        a = _attrs(step['path']) if step['written'] else None
        start = os.path.basename(step['parent']) or 'spheroid'
        wall = 'reused' if step['wall'] is None else f"{step['wall']:.1f}"
        if a is None:
            rows.append(f"| {step['v']:g} | {start} | no checkpoint |  |  |  |  | 0 |  |  |  |  |  "
                        f"|  | {wall} |")
            continue
        total += float(a['wall_time'])
        # A run whose phi_h has no zero level set has no sharp comparison.
        compared = ([f"{a['sharp_energy']:.5f}", f"{100 * a['sharp_rel_error']:+.2f}%",
                     f"{a['sharp_dist_max']:.4f}"] if 'sharp_energy' in a else ['', '', ''])
        rows.append(
            f"| {step['v']:g} | {start} | {a['energy']:.5f} | {a['nu_area']:.4f} | {a['nu_volume']:.3f} "
            f"| {a['max_phi']:.4f} | {iterations(a['stage1_iterations'])}+{iterations(a['stage2_iterations'])} "
            f"| {int(a['converged'])} | {' | '.join(compared)} | {a.get('topology', '')} "
            f"| {' '.join(map(str, a['index_m'])) if 'index_m' in a else ''} "
            f"| {a['wall_time']:.1f} | {wall} |")
    return rows, total


def header(branch, vs, box, need, sizes, given, args, record):
    """The title, the provenance line of `record` (`report.provenance`) and the
    paragraph above the table: scene, grid, box and how to read the columns."""
    n_nodes, spacing = uniform_grid(box, args.nodes)
    rb, zb = box
    why = ('given by --box' if given else
           f"the paper's {PAPER_BOX[0]:g} x {PAPER_BOX[1]:g}"
           + (', grown to hold the branch' if box != PAPER_BOX else ''))
    return (
        '\n'.join(report.header(f"The {branch} branch: continuation in the reduced volume",
                                record)) + '\n'
        f"Scene `{SCENE.format(branch)}`, eps = {args.eps:g}, a uniform grid of {n_nodes} nodes "
        f"(`-pf_nodes {args.nodes}`, mean nodal spacing {spacing:.4f}), "
        f"{args.np} MPI ranks, {os.cpu_count()} cores. v = {vs[0]:g} starts from the {branch} "
        f"spheroid; every next v restarts from the checkpoint of the one before (column start)."
        + (f" Options added to the runs of this invocation: `{' '.join(args.options)}`."
           if args.options else '')
        + "\n\n"
        f"Box Rb x Zb = {rb:g} x {zb:g} ({why}): it holds every shape of the branch for v from "
        f"{vs[0]:g} to {vs[-1]:g} with a margin of {MARGIN:g} eps = {MARGIN * args.eps:g}, which "
        f"needs Rb >= {need[0]:.4f} and Zb >= {need[1]:.4f}: "
        f"sharp-interface shapes reach r = {sizes['sharp'][0]:.4f} and |z - Zb/2| = "
        f"{sizes['sharp'][1]:.4f}; the initial spheroids have semi-axes up to "
        f"a = {sizes['spheroid'][0]:.4f}, "
        f"c = {sizes['spheroid'][1]:.4f}.\n\n"
        "E_sharp: the axisymmetric Canham-Helfrich shape of the same scene (checkpoint attribute "
        "`sharp_energy`); error vs sharp = (E - E_sharp) / E_sharp; d max: largest distance from "
        "phi_h = 0 to the sharp curve (a jump to another branch shows here). index per m: the "
        "negative eigenvalues of the second variation in each azimuthal mode m = 0, 1, ... "
        "(`-pf_modes M`; rigid motions excluded), 0 everywhere for a stable shape. run s: the step's "
        "own wall time (grid set-up on the first); wall s: this invocation's, checkpoint included.\n\n"
        f"Regenerate: `python runs/branches/branch.py --branch {branch} --from {vs[0]:g} "
        f"--to {vs[-1]:g} --step {args.step:g} --out {shown(args.out)} --np {args.np} --eps {args.eps:g} "
        f"--nodes {args.nodes}{f' --box {rb:g},{zb:g}' if given else ''} --force"
        f"{' -- ' + ' '.join(args.options) if args.options else ''}`.\n\n")


def continuation(args):
    """Run one branch and write its table; returns the exit status."""
    try:
        vs = volumes(args.start, args.stop, args.step)
    except ValueError as e:
        print(f"{NAME}: {e}", file=sys.stderr)
        return 2
    scene = SCENE.format(args.branch)
    radius, c0, k = (scene_value(scene, name) for name in ('radius', 'c0', 'k'))
    need, sizes = required_box(args.branch, vs, args.eps, radius, c0, k, margin=MARGIN)
    box = args.box or default_box(need)
    if box[0] < need[0] or box[1] < need[1]:
        print(f"{NAME}: --box {box[0]:g},{box[1]:g} cannot hold the {args.branch} "
              f"branch from v = {vs[0]:g} to {vs[-1]:g} with a margin of {MARGIN:g} eps: "
              f"need Rb >= {need[0]:.4f}, Zb >= {need[1]:.4f}", file=sys.stderr)
        return 2
    launch.ensure_ranks(args.np, __file__, sys.argv[1:])
    record = report.provenance()   # before the measurement (and before MPI starts)
    t0 = time.time()
    steps = run(args.branch, vs, box, args)
    elapsed = time.time() - t0
    from mpi4py import MPI
    if MPI.COMM_WORLD.Get_rank() != 0:
        return 1 if any(s['status'] for s in steps) else 0
    rows, total = table(steps)
    failed = [s for s in steps if s['status'] != 0]
    notes = []
    if failed:
        s = failed[0]
        left = vs[len(steps):]
        notes.append(f"v = {s['v']:g} failed with exit status {s['status']}"
                     f"{': ' + s['message'] if s['message'] else ''}. The branch stops there"
                     + (f"; not run: v = {', '.join(f'{v:g}' for v in left)}." if left else "."))
    notes.append(f"Sum of the runs' wall times: {total:.1f} s (this invocation: {elapsed:.1f} s).")
    out = os.path.join(args.out, f"{args.branch}.md")
    os.makedirs(args.out, exist_ok=True)
    with open(out, 'w') as f:
        f.write(header(args.branch, vs, box, need, sizes, args.box is not None, args, record))
        f.write('\n'.join(rows) + '\n\n' + '\n\n'.join(notes) + '\n')
    print('\n'.join(rows + notes))
    print(out)
    return 1 if failed else 0


def checkpoints(directory):
    """The checkpoints of every branch under `directory`: {branch: [(path, Checkpoint)]}
    in order of v (`pf.read(path).checkpoint()`)."""
    found = {}
    for branch in BRANCHES:
        pairs = [(p, pf.read(p).checkpoint())
                 for p in glob.glob(os.path.join(directory, branch, 'v*.h5'))]
        if pairs:
            found[branch] = sorted(pairs, key=lambda pair: pair[1].attrs['reduced_volume'])
    return found


def plot(directory, dpi=150):
    """Draw `directory`/energy.png: E(v) of the branches, their sharp-interface
    energies and the shapes.

    Not collective.  Phase-field energies are points (open where a run did not
    converge); the sharp-interface energies (`pfmembrane.analysis.levelset.reference`) are
    lines on a v grid `SHARP_DV` apart up to the sphere, v = 1. Below, one strip
    per branch shows the zero level set of phi_h (`pfmembrane.analysis.levelset.level_set`)
    of each checkpoint at its v, mirrored about the axis, over the sharp curve,
    all at one scale.

    Returns
    -------
    str
        Path of the figure.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.transforms import blended_transform_factory
    # limit initializes PETSc, hence MPI: a process that starts mpiexec must not.
    from pfmembrane.analysis.levelset import membrane, reference

    found = {branch: [c for _, c in pairs] for branch, pairs in checkpoints(directory).items()}
    if not found:
        raise FileNotFoundError(f"no checkpoints under {directory}/<branch>/v*.h5")
    figure = plt.figure(figsize=(10.0, 4.5 + 2.0 * len(found)))
    grid = figure.add_gridspec(1 + len(found), 1, height_ratios=[4.5] + [2.0] * len(found))
    energy = figure.add_subplot(grid[0])
    v_all = [c.attrs['reduced_volume'] for ckpts in found.values() for c in ckpts]
    shapes = {}
    for (branch, ckpts), colour in zip(found.items(), ('tab:blue', 'tab:red')):
        a = ckpts[0].attrs
        scene = (a['c0'], a['radius'], a['k'])
        v = np.array([c.attrs['reduced_volume'] for c in ckpts])
        e = np.array([c.attrs['energy'] for c in ckpts])
        ok = np.array([bool(c.attrs['converged']) for c in ckpts])
        energy.plot(v[ok], e[ok], 'o', color=colour,
                    label=f"{branch}, phase field (eps = {a['eps']:g}, N = {len(ckpts[0].nodes)})")
        if not ok.all():
            energy.plot(v[~ok], e[~ok], 'o', mfc='none', color=colour, label=f"{branch}, not converged")
        # Rounded, so that the checkpoints' own v hit the cache of the sharp solves.
        count = int(round((1.0 - min(v_all)) / SHARP_DV)) + 1
        fine = np.round(np.linspace(min(v_all), 1.0, count), 10)
        sharp_line = [_sharp(reference, branch, x, scene) for x in fine]
        energy.plot(fine, [np.nan if s is None else s.energy for s in sharp_line], '-',
                    color=colour, label=f"{branch}, sharp interface")
        shapes[branch] = [(c.attrs['reduced_volume'], _silhouette(membrane, c),
                           _sharp(reference, branch, c.attrs['reduced_volume'], scene)) for c in ckpts]
    energy.set_ylabel('E')
    energy.set_title('Bending energy along the branches')
    energy.legend(fontsize='small')
    energy.grid(alpha=0.3)
    step = np.min(np.diff(np.unique(v_all))) if len(set(v_all)) > 1 else 0.05
    energy.set_xlim(min(v_all) - 0.6 * step, 1.0 + 0.1 * step)
    half = 1.05 * max((np.max(np.abs(np.vstack(pieces))) for entries in shapes.values()
                       for _, pieces, _ in entries if pieces), default=1.0)
    for row, (branch, entries) in enumerate(shapes.items(), start=1):
        strip = figure.add_subplot(grid[row], sharex=energy)
        strip.set_yticks([])
        strip.set_ylabel(branch)
        place = blended_transform_factory(strip.transData, strip.transAxes)
        for v, pieces, shape in entries:
            inset = strip.inset_axes([v - 0.45 * step, 0.0, 0.9 * step, 1.0], transform=place)
            for piece in pieces:
                inset.fill(piece[:, 0], piece[:, 1], color='tab:grey', alpha=0.6, linewidth=0)
            if shape is not None:
                # The mirror starts one point in: a repeated vertex draws a spike at the pole.
                inset.plot(np.concatenate([shape.r, -shape.r[-2::-1]]),
                           np.concatenate([shape.z, shape.z[-2::-1]]), color='k', linewidth=0.6)
            inset.set_xlim(-half, half)
            inset.set_ylim(-half, half)
            inset.set_aspect('equal')
            inset.set_axis_off()
    strip.set_xlabel('reduced volume v')
    energy.tick_params(labelbottom=False)
    out = os.path.join(directory, 'energy.png')
    figure.savefig(out, dpi=dpi, bbox_inches='tight')
    plt.close(figure)
    return out


def _sharp(reference, branch, v, scene):
    """The sharp-interface shape, None where the sharp solver loses the branch."""
    try:
        return reference(branch, v, *scene)
    except RuntimeError:
        return None


def _silhouette(membrane, ckpt):
    """Closed outlines of phi_h = 0 mirrored about the axis, centred at Zb / 2;
    [] where the level set cannot be found."""
    pieces = membrane(ckpt)
    centre = np.array([0.0, 0.5 * ckpt.box[1]])
    return [np.vstack([p - centre, (p - centre)[-2::-1] * [-1.0, 1.0]]) for p in pieces]


def _box(text):
    try:
        box = tuple(float(t) for t in text.split(','))
    except ValueError:
        box = ()
    if len(box) != 2 or not all(b > 0 for b in box):
        raise argparse.ArgumentTypeError(f"expected two positive numbers Rb,Zb (got {text!r})")
    return box


def main(argv=None):
    ap = argparse.ArgumentParser(prog='python runs/branches/branch.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--branch', choices=BRANCHES)
    ap.add_argument('--from', dest='start', type=float, default=0.95, help='first reduced volume')
    ap.add_argument('--to', dest='stop', type=float, default=0.65, help='last reduced volume')
    ap.add_argument('--step', type=float, default=0.05, help='reduced-volume step')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'branches'),
                    help='directory of the checkpoints (OUT/<branch>/) and tables '
                         '(default: runs/branches of the repository)')
    ap.add_argument('--np', type=int, default=2, help='MPI ranks')
    ap.add_argument('--eps', type=float, default=0.04, help='regularization width')
    ap.add_argument('--nodes', type=int, default=6124, help='node count of the uniform grid')
    ap.add_argument('--box', type=_box, help='Rb,Zb (default: see the module documentation)')
    ap.add_argument('--force', action='store_true', help='rerun steps with a reusable checkpoint')
    ap.add_argument('--plot', metavar='OUT', help='draw OUT/energy.png from the checkpoints under OUT')
    ap.add_argument('options', nargs='*', metavar='-- OPTION',
                    help='further options of every run, e.g. -- -pf_stage1_rtol 1e-5')
    args = ap.parse_args(argv)
    if args.plot:
        try:
            print(plot(args.plot))
        except FileNotFoundError as e:
            print(f"{NAME}: {e}", file=sys.stderr)
            return 1
        return 0
    if not args.branch:
        ap.error('give --branch (or --plot OUT)')
    return continuation(args)


if __name__ == '__main__':
    sys.exit(main())
