"""Speed and accuracy benchmarks under runs/bench/.

    python runs/bench/bench.py basis [--out runs/bench] [--nodes 6124,24597,98388] [--np 1,2]
    python runs/bench/bench.py solve [--out runs/bench] [--quick] [--force]

`basis` times the set-up of uniform grids (node generation, nodal spacing,
triangulation and partition, max-ent basis: `pfmembrane.analysis.timing.measure_grid`)
and reports their size, the mean support of the basis and the peak memory per rank;
each measurement is one `mpiexec -n NP python runs/bench/bench.py basis-one` that
prints a JSON line.

`solve` runs the configurations of RUNS (one `mpiexec -n NP python -m
pfmembrane` each, reusing a checkpoint that exists unless --force), compares
the energies with the paper's finest uniform grid and the sharp-interface
model, draws the error against the wall time with its Pareto front, and names
the cheapest configuration reaching 1%, 0.5% and 0.2% of the sharp-interface
energy.

Runs from any working directory: --out defaults to the repository's runs/bench, and the
runs are made from the repository's root (the scenes are its options files), paths inside
it shown relative to it.
"""
import argparse
import contextlib
import json
import math
import os
import subprocess
import sys
from dataclasses import dataclass

import numpy as np

import pfmembrane as pf
from pfmembrane import paper, report
from pfmembrane import series as launch
from pfmembrane.analysis.timing import measure_grid
from pfmembrane.paper import PAPER_BOX

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The paper's finest uniform grid (296,344 nodes) per eps, and the sharp interface.
BRANCH = {'discocyte': 'oblate', 'dumbbell': 'prolate'}
FINEST = {scene: paper.UNIFORM[(branch, paper.FINEST)] for scene, branch in BRANCH.items()}
SHARP = {scene: paper.SHARP[branch] for scene, branch in BRANCH.items()}
SCENES = {'discocyte': 'options/discocyte.opts', 'dumbbell': 'options/dumbbell.opts'}

# -pf_* values shared by every run unless a row of RUNS changes them.
BASELINE = {'nodes': 6124, 'eps': 0.04, 'gamma': 0.8, 'cutoff': 1e-6, 'quad_degree': 4,
            'stage1': 'newton'}


def adaptive(prefix, changes):
    """The paper's progressive adaptation (Table B.6, as options/adapt/discocyte):
    a uniform start, then CVT steps with f = 10, 100, 1000 (stage 2 straight
    from the transferred phi) and eps lowered on each grid, gamma 0.5."""
    steps = [('g0.5', None, 0, 0.04), ('f10-eps0.04', 'g0.5', 10, 0.04),
             ('f10-eps0.03', 'f10-eps0.04', 0, 0.03), ('f100-eps0.03', 'f10-eps0.03', 100, 0.03),
             ('f100-eps0.025', 'f100-eps0.03', 0, 0.025),
             ('f1000-eps0.025', 'f100-eps0.025', 1000, 0.025),
             ('f1000-eps0.02', 'f1000-eps0.025', 0, 0.02), ('f1000-eps0.015', 'f1000-eps0.02', 0, 0.015),
             ('f1000-eps0.01', 'f1000-eps0.015', 0, 0.01)]
    rows = []
    for label, start, f, eps in steps:
        row = dict(changes, gamma=0.5, eps=eps)
        if start:
            row['restart'] = prefix + start
        if f:
            row.update(adapt=f, stage1='none')
        rows.append((prefix + label, 2, row))
    return rows


# One row per run and scene: (label, MPI ranks, changes to BASELINE). One knob
# at a time around the baseline, then finer uniform grids, then the paper's
# progressive adaptation on the full and on the half box: `restart` names an
# earlier row of the same scene (or a checkpoint path ending in .h5) whose
# nodes are adapted with density amplification `adapt` to its phi. Keys that
# start with '-' are PETSc options, passed as they are.
RUNS = [
    ('base', 2, {}),
    ('np1', 1, {}),
    ('eps0.05', 2, {'eps': 0.05}),
    ('gamma0.6', 2, {'gamma': 0.6}),
    ('gamma1.0', 2, {'gamma': 1.0}),
    ('cutoff1e-4', 2, {'cutoff': 1e-4}),
    ('cutoff1e-9', 2, {'cutoff': 1e-9}),
    ('quad2', 2, {'quad_degree': 2}),
    ('quad5', 2, {'quad_degree': 5}),
    ('tao', 2, {'stage1': 'tao'}),
    ('superlu', 2, {'-stage1_pc_type': 'lu', '-stage1_pc_factor_mat_solver_type': 'superlu_dist',
                    '-stage2_pc_factor_mat_solver_type': 'superlu_dist'}),
    ('half-box', 2, {'symmetric': 'true'}),
    ('n12271', 2, {'nodes': 12271}),
    ('n24597', 2, {'nodes': 24597}),
    ('n12271-eps0.03', 2, {'nodes': 12271, 'eps': 0.03}),
    ('n24597-eps0.03', 2, {'nodes': 24597, 'eps': 0.03}),
    *adaptive('', {}),
    *adaptive('half-', {'symmetric': 'true'}),
]

# --quick: a few seconds per run, 1000 nodes in a smaller box; the adapted
# run restarts from the first one, and its eps 0.05 has a finest-grid
# reference, so the Pareto figure gets a point.
QUICK_BASELINE = dict(BASELINE, nodes=1000, box='0.8,1.0', eps=0.06)
QUICK_RUNS = [
    ('quick', 2, {}),
    ('quick-np1', 1, {}),
    ('quick-f10-eps0.05', 2, {'restart': 'quick', 'adapt': 10, 'eps': 0.05}),
]
QUICK_SCENES = ('discocyte',)
QUICK_NOTE = (' (this is the --quick set: its box is smaller and its grid coarser than '
              "the references', so its errors only exercise the report)")

THRESHOLDS = (0.01, 0.005, 0.002)

BASIS_NODES = (6124, 24597, 98388)
BASIS_BOX = PAPER_BOX
BASIS_GAMMA, BASIS_CUTOFF, BASIS_DEGREE = 0.8, 1e-6, 4
TIME_ATTRS = ('time_setup', 'time_stage1', 'time_stage2', 'time_assembly', 'time_linear')
NAN = float('nan')


def _fmt(value, spec):
    """`value` formatted with `spec`, or a dash when it was not measured."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return '—'
    return format(value, spec)


def _percent(value):
    """A relative error in per cent, or a dash when there is no reference."""
    return _fmt(100 * value, '+.2f') + ('%' if _finite(value) else '')


def _finite(value):
    return value is not None and math.isfinite(value)


def _rule(header):
    """The markdown separator line under a table header."""
    return '|' + '---|' * (header.count(' | ') + 1)


def _json_ready(obj):
    """NaN to null, so that the JSON files are standard JSON."""
    if isinstance(obj, dict):
        return {k: _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def _write_json(path, obj):
    with open(path, 'w') as f:
        json.dump(_json_ready(obj), f, indent=1)
        f.write('\n')


# ---------------------------------------------------------------- basis set-up

def basis_one(args):
    """One `measure_grid` on the ranks of this mpiexec; rank 0 prints its JSON line."""
    import petsc4py
    petsc4py.init(sys.argv[:1])
    from petsc4py import PETSc

    comm = PETSc.COMM_WORLD
    try:
        result = measure_grid(comm, args.nodes, BASIS_BOX, BASIS_GAMMA, BASIS_CUTOFF,
                              BASIS_DEGREE)
    except BaseException as e:  # noqa: BLE001 - one rank's failure must end all ranks
        sys.stderr.write(f"bench.py: rank {comm.getRank()}: {type(e).__name__}: {e}\n")
        sys.stderr.flush()
        comm.tompi4py().Abort(4)
    if comm.getRank() == 0:
        print(json.dumps(result), flush=True)


BASIS_COLUMNS = ('| requested | nodes | free | quadrature points | points per node '
                 '| mean support | ranks | nodes s | spacing s | triangulation + partition s '
                 '| max-ent basis s | operators s | total s | peak MB/rank | grid MB/rank |')


def basis_row(r):
    s = r['seconds']
    return (f"| {r['requested']} | {r['nodes']} | {r['free_nodes']} | {r['quadrature_points']} | "
            f"{r['quadrature_points'] / r['nodes']:.2f} | {r['mean_support']:.1f} | {r['ranks']} | "
            f"{s['nodes']:.2f} | {s['spacing']:.2f} | {s['partition']:.2f} | {s['basis']:.2f} | "
            f"{s['operators']:.2f} | {s['nodes'] + s['grid']:.2f} | {r['peak_rss_mb']:.0f} | "
            f"{r['grid_rss_mb']:.0f} |")


def basis(args):
    """Measure every (node count, ranks) pair; write basis.md and basis.json."""
    os.makedirs(args.out, exist_ok=True)
    record = report.provenance()
    results = []
    for n in (int(v) for v in args.nodes.split(',')):
        for ranks in (int(v) for v in args.np.split(',')):
            cmd = launch.command(ranks, 'basis-one', '--nodes', str(n), module=__file__)
            print(' '.join(cmd), flush=True)
            proc = launch.run(cmd, stdout=subprocess.PIPE, text=True, check=False)
            if proc.returncode != 0:
                raise SystemExit(f"bench.py: exit status {proc.returncode} from "
                                 f"{' '.join(cmd)}")
            results.append(json.loads(proc.stdout.strip().splitlines()[-1]))
            print(basis_row(results[-1]), flush=True)
    lines = [*report.header('Basis set-up', record),
             f"Uniform grids in the {BASIS_BOX[0]:g} x {BASIS_BOX[1]:g} box: max-ent basis with "
             f"gamma {BASIS_GAMMA:g}, cut-off {BASIS_CUTOFF:g} and second derivatives at the "
             f"points of the degree-{BASIS_DEGREE} Gauss rule. Seconds are the largest over the "
             "ranks: node generation, nodal spacing, triangulation + partition (Delaunay "
             "triangles, graph partition of the free nodes, this rank's Gauss points), max-ent "
             "basis (values and derivatives), operators (axis mirrors, the sparse B0, Br, Bz, "
             "BL and their ghosts). `mean support` is the mean number of basis functions per "
             "quadrature point (axis mirrors counted); `grid MB` is the growth of the peak RSS "
             "while the grid was built. Regenerate: `make bench-basis`.", '',
             BASIS_COLUMNS, _rule(BASIS_COLUMNS)]
    lines += [basis_row(r) for r in results]
    path = os.path.join(args.out, 'basis.md')
    report.write(path, lines)
    _write_json(os.path.join(args.out, 'basis.json'), {'provenance': record, 'results': results})
    print(path)


# ---------------------------------------------------------------- solves

@dataclass
class Config:
    """One run: `options` are the -pf_* values, `restart` a checkpoint path or ''."""
    name: str
    label: str
    scene: str
    ranks: int
    options: dict
    restart: str


def configurations(out, quick=False):
    """The runs of RUNS (or QUICK_RUNS) for every scene, in table order."""
    baseline, runs, scenes = ((QUICK_BASELINE, QUICK_RUNS, QUICK_SCENES) if quick
                              else (BASELINE, RUNS, tuple(SCENES)))
    configs = []
    for scene in scenes:
        for label, ranks, changes in runs:
            options = dict(baseline, **changes)
            restart = options.pop('restart', '')
            if restart:
                options.pop('nodes')  # the restart checkpoint gives the nodes
                if not restart.endswith('.h5'):
                    restart = os.path.join(out, f"{scene}-{restart}.h5")
            configs.append(Config(f"{scene}-{label}", label, scene, ranks, options, restart))
    return configs


def command(config, path):
    """The mpiexec command line of a run writing its checkpoint to `path`."""
    cmd = launch.command(config.ranks, '-options_file', SCENES[config.scene])
    for key, value in config.options.items():
        cmd += [key if key.startswith('-') else f"-pf_{key}", str(value)]
    if config.restart:
        cmd += ['-pf_restart', config.restart]
    return cmd + ['-pf_output', path]


def run(config, out, force=False):
    """Run `config` unless its checkpoint exists; return its checkpoint path and
    the reason it has none (None when it has one)."""
    path = os.path.join(out, config.name + '.h5')
    if force and os.path.exists(path):
        os.remove(path)  # a refused rerun must not leave the old result in place
    if os.path.exists(path):
        return path, None
    if config.restart and not os.path.exists(config.restart):
        return path, f"restart checkpoint {config.restart} missing"
    cmd = command(config, path)
    print(' '.join(cmd), flush=True)
    proc = launch.run(cmd, stderr=subprocess.PIPE, text=True, check=False)
    sys.stderr.write(proc.stderr)
    if os.path.exists(path):
        return path, None
    lines = [line for line in proc.stderr.splitlines() if line.startswith('pfmembrane')]
    return path, (lines[0] if lines else f"exit status {proc.returncode}, no checkpoint")


def record(config, path, costs):
    """The measurements of one checkpoint as a flat dict.

    `cost` is the wall time of the run plus that of the run it restarted
    from (from `costs`, by checkpoint path, else from the checkpoint itself):
    an adapted grid is only as cheap as the runs that led to it. `moved` says
    whether a restarted run's nodes differ from those it started from, i.e.
    whether -pf_adapt took effect.
    """
    res = pf.read(path)
    a, nodes = res.attrs, res.nodes
    scene, eps, energy = config.scene, float(a['eps']), float(a['energy'])
    finest = FINEST[scene].get(round(eps, 6), NAN)
    previous, moved = 0.0, False
    if config.restart:
        start = pf.read(config.restart)
        previous = costs.get(config.restart, float(start.attrs['wall_time']))
        moved = not np.array_equal(nodes, start.nodes)
    rec = {'name': config.name, 'label': config.label, 'scene': scene,
           'ranks': int(a['n_procs']), 'nodes': int(a.get('n_nodes', -1)), 'eps': eps,
           'gamma': float(a['gamma']), 'cutoff': float(a.get('cutoff', NAN)),
           'quad_degree': int(a.get('quad_degree', -1)), 'stage1': config.options['stage1'],
           'adapt': float(config.options.get('adapt', 0.0)), 'restart': config.restart,
           'symmetric': int(a.get('symmetric', 0)),
           'moved': moved,
           'energy': energy, 'finest': finest, 'error_finest': energy / finest - 1.0,
           'error_sharp': energy / SHARP[scene] - 1.0, 'converged': int(a['converged']),
           'under_resolved': int(a.get('under_resolved', 0)),
           'stage1_iterations': int(a.get('stage1_iterations', -1)),
           'stage2_iterations': int(a.get('stage2_iterations', -1)),
           'wall_time': float(a['wall_time']), 'cost': float(a['wall_time']) + previous,
           'peak_rss_mb': float(a.get('peak_rss_mb', NAN)), 'checkpoint': path}
    rec.update({name: float(a.get(name, NAN)) for name in TIME_ATTRS})
    return rec


def usable(rec):
    """A converged run on a grid that resolves its eps."""
    return rec['converged'] == 1 and rec['under_resolved'] == 0


def pareto_front(records, cost='cost', error='error'):
    """The records no other record beats in both `cost` and |`error`|.

    A record is dominated when another one is no more expensive and no less
    accurate, and strictly better in one of the two; of records equal in
    both, the first is kept. Records whose error is not finite are ignored.

    Returns
    -------
    list of dict
        The non-dominated records by increasing cost (so by decreasing error).
    """
    points = sorted((r for r in records if _finite(r[error])),
                    key=lambda r: (r[cost], abs(r[error])))
    front, best = [], math.inf
    for r in points:
        if abs(r[error]) < best:
            front.append(r)
            best = abs(r[error])
    return front


def recommend(records, scene, thresholds=THRESHOLDS):
    """For every threshold, the cheapest usable run of `scene` whose energy is
    within it of the sharp-interface energy, or None.

    Returns
    -------
    dict
        threshold -> record or None.
    """
    runs = [r for r in records if r['scene'] == scene and usable(r)]
    choice = {}
    for tol in thresholds:
        good = [r for r in runs if abs(r['error_sharp']) <= tol]
        choice[tol] = min(good, key=lambda r: (r['cost'], r['name'])) if good else None
    return choice


def recommendation(records, thresholds=THRESHOLDS):
    """One plain-words paragraph per scene from `recommend`."""
    paragraphs = []
    for scene in dict.fromkeys(r['scene'] for r in records):
        runs = [r for r in records if r['scene'] == scene and usable(r)]
        if not runs:
            paragraphs.append(f"**{scene.capitalize()}**: no converged run measured.")
            continue
        parts = []
        for tol, r in recommend(records, scene, thresholds).items():
            if r is None:
                parts.append(f"{100 * tol:g}%: none measured reaches it")
            else:
                parts.append(f"{100 * tol:g}%: `{r['label']}` ({_describe(r)}; "
                             f"{100 * r['error_sharp']:+.2f}%, {r['cost']:.0f} s)")
        closest = min(runs, key=lambda r: abs(r['error_sharp']))
        text = (f"**{scene.capitalize()}** (sharp-interface E = {SHARP[scene]}): the cheapest "
                "converged configuration within " + '; within '.join(parts) + ". The closest "
                f"measured is `{closest['label']}` at {100 * closest['error_sharp']:+.2f}% "
                f"({closest['cost']:.0f} s)")
        if _finite(closest['error_finest']) \
                and abs(closest['error_finest']) < 0.2 * abs(closest['error_sharp']):
            text += (f", only {100 * closest['error_finest']:+.2f}% from the finest uniform "
                     f"grid at its eps {closest['eps']:g}: the rest is the phase-field error "
                     "of eps itself, which only a smaller eps (with the nodes to resolve it) "
                     "removes")
        paragraphs.append(text + '.')
    return '\n\n'.join(paragraphs)


def _describe(r):
    text = (f"{r['nodes']} nodes, eps {r['eps']:g}, gamma {r['gamma']:g}, cut-off "
            f"{r['cutoff']:g}, degree {r['quad_degree']}, {r['stage1']}, {r['ranks']} "
            f"rank{'s' if r['ranks'] > 1 else ''}")
    if r.get('symmetric'):
        text += ", half box"
    if r['moved']:
        text += f", adapted with f = {r['adapt']:g} from {os.path.basename(r['restart'])}"
    return text


SOLVE_COLUMNS = ('| run | ranks | nodes | eps | gamma | cut-off | quad | stage 1 | f | E '
                 '| E finest | vs finest | vs sharp | its (1+2) | conv | wall s | cost s '
                 '| set-up s | stage 1 s | stage 2 s | assembly s | linear s | peak MB/rank |')


def solve_row(r):
    return (f"| {r['label']} | {r['ranks']} | {r['nodes']} | {r['eps']:g} | {r['gamma']:g} | "
            f"{r['cutoff']:g} | {r['quad_degree']} | {r['stage1']} | {r['adapt']:g}"
            f"{' (nodes unchanged)' if r['adapt'] and not r['moved'] else ''} | "
            f"{r['energy']:.5f} | {_fmt(r['finest'], '.5f')} | "
            f"{_percent(r['error_finest'])} | {_percent(r['error_sharp'])} | "
            f"{max(r['stage1_iterations'], 0) or '-'}+{r['stage2_iterations']} | {r['converged']}"
            f"{' (under-resolved)' if r['under_resolved'] else ''} | {r['wall_time']:.1f} | "
            f"{r['cost']:.1f} | "
            + ' | '.join(_fmt(r[name], '.1f') for name in TIME_ATTRS)
            + f" | {_fmt(r['peak_rss_mb'], '.0f')} |")


def solve_markdown(records, missing, record, quick):
    """solve.md: one table per scene, the runs without a checkpoint, the recommendation;
    `record` is the `report.provenance` of the measurement."""
    lines = [*report.header('Speed against accuracy of full solves', record),
             'Phase-field solves. `vs finest`: relative energy error against the paper\'s '
             'uniform grid of 296,344 nodes at the same eps; `vs sharp`: against the '
             'sharp-interface energy. `wall s` is the checkpoint\'s wall time; `cost s` adds '
             'the runs an adapted grid restarted from. The time split (set-up, stages, '
             'Hessian and gradient assembly, linear solves) is the largest over the ranks; '
             'a dash means the checkpoint does not record it. Checkpoints that existed were '
             'reused, so their times date from their own run. `pareto.png` plots |vs finest| '
             'against the cost per scene: crosses did not converge or are under-resolved, the '
             'step line is the Pareto front of the others. Regenerate: `make bench`'
             f"{QUICK_NOTE if quick else ''}."]
    for scene in dict.fromkeys([r['scene'] for r in records] + [c.scene for c, _ in missing]):
        lines += ['', f"## {scene.capitalize()}", '', SOLVE_COLUMNS, _rule(SOLVE_COLUMNS)]
        lines += [solve_row(r) for r in records if r['scene'] == scene]
        lost = [(c, why) for c, why in missing if c.scene == scene]
        if lost:
            lines += ['', 'No checkpoint:'] + [f"- `{c.label}`: {why}" for c, why in lost]
    lines += ['', '## Recommendation', '', recommendation(records)]
    return '\n'.join(lines) + '\n'


def plot_pareto(records, path):
    """Error against the finest uniform grid versus wall time, one panel per scene."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    scenes = list(dict.fromkeys(r['scene'] for r in records)) or ['(no runs)']
    fig = Figure(figsize=(6.0 * len(scenes), 4.8))
    FigureCanvasAgg(fig)
    for k, scene in enumerate(scenes):
        ax = fig.add_subplot(1, len(scenes), k + 1)
        runs = [r for r in records if r['scene'] == scene
                and _finite(r['error_finest']) and r['error_finest'] != 0.0]
        for r in runs:
            # Crosses: not converged or under-resolved.
            marker, color = ('o', 'C0') if usable(r) else ('x', 'C3')
            ax.loglog(r['cost'], 100 * abs(r['error_finest']), marker, color=color)
            ax.annotate(r['label'], (r['cost'], 100 * abs(r['error_finest'])), fontsize=7,
                        xytext=(3, 3), textcoords='offset points')
        front = pareto_front([r for r in runs if usable(r)], error='error_finest')
        if front:
            # The last step runs to the most expensive run: no budget up to there does better.
            costs = [r['cost'] for r in front] + [max(r['cost'] for r in runs)]
            errors = [100 * abs(r['error_finest']) for r in front]
            ax.step(costs, errors + errors[-1:], where='post', color='C1',
                    label='Pareto front (converged runs)')
            ax.legend(fontsize=8)
        else:
            ax.text(0.5, 0.5, 'no converged run with a finest-grid reference',
                    transform=ax.transAxes, ha='center')
        ax.set_title(scene)
        ax.set_xlabel('wall time (s, restarts included)')
        ax.set_ylabel('|E / E_finest(eps) - 1| (%)')
        ax.grid(True, which='both', alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def solve(args):
    """Run the configurations; write solve.md, solve.json and pareto.png."""
    os.makedirs(args.out, exist_ok=True)
    provenance = report.provenance()
    records, missing, costs = [], [], {}
    for config in configurations(args.out, args.quick):
        path, why = run(config, args.out, args.force)
        if why is not None:
            missing.append((config, why))
            print(f"{config.name}: {why}", flush=True)
            continue
        records.append(record(config, path, costs))
        costs[path] = records[-1]['cost']
        print(solve_row(records[-1]), flush=True)
    with open(os.path.join(args.out, 'solve.md'), 'w') as f:
        f.write(solve_markdown(records, missing, provenance, args.quick))
    _write_json(os.path.join(args.out, 'solve.json'), {
        'provenance': provenance, 'finest': {s: {str(k): v for k, v in e.items()} for s, e in FINEST.items()},
        'sharp': SHARP, 'runs': records,
        'missing': [{'name': c.name, 'reason': why} for c, why in missing]})
    plot_pareto(records, os.path.join(args.out, 'pareto.png'))
    print(recommendation(records))
    print(os.path.join(args.out, 'solve.md'))


def from_root(path):
    """`path` (from the working directory) relative to the repository's root when it is
    inside it, else absolute: the runs are made from the root."""
    path = os.path.abspath(path)
    rel = os.path.relpath(path, ROOT)
    return path if rel.startswith(os.pardir) else rel


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest='command', required=True)
    b = sub.add_parser('basis', help='set-up time, size and memory of the max-ent basis')
    b.add_argument('--out', default=os.path.join(ROOT, 'runs', 'bench'))
    b.add_argument('--nodes', default=','.join(map(str, BASIS_NODES)))
    b.add_argument('--np', default='1,2')
    one = sub.add_parser('basis-one', help='one basis measurement (run under mpiexec)')
    one.add_argument('--nodes', type=int, required=True)
    s = sub.add_parser('solve', help='speed and accuracy of full solves')
    s.add_argument('--out', default=os.path.join(ROOT, 'runs', 'bench'))
    s.add_argument('--quick', action='store_true', help='three small runs (testing)')
    s.add_argument('--force', action='store_true', help='rerun even if a checkpoint exists')
    args = ap.parse_args(argv)
    if args.command == 'basis-one':
        basis_one(args)
        return 0
    args.out = from_root(args.out)
    with contextlib.chdir(ROOT):
        {'basis': basis, 'solve': solve}[args.command](args)
    return 0


if __name__ == '__main__':
    sys.exit(main())
