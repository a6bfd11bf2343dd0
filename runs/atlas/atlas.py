"""The shape atlas: branches in v by pseudo-arclength continuation, and the phase diagram.

    python runs/atlas/atlas.py [--np 2] [--groups 1] [--eps 0.02] [--nodes 40000]
        [--families prolate oblate stomatocyte pear] [--c0 X ...] [--ds 0.05] [--steps 120]
        [--box Rb,Zb] [--gamma 0.8] [--adapt F --coarse DIR [--band W]] [--out runs/atlas] [--force]
        [-- SOLVER OPTIONS]
    python runs/atlas/atlas.py --plot runs/atlas
    python runs/atlas/atlas.py --merge runs/atlas runs/atlas/stomatocyte --out DIR

From any working directory: --out defaults to runs/atlas of the repository; paths given are
the caller's.

Each branch is a family (`FAMILIES`) at one reduced spontaneous curvature c0 = 2 C0 R: one
grid of the spacing of NODES nodes in the paper box, in a box holding the family's sharp
shapes over its range of v with MARGIN eps (the half box for the up-down symmetric ones), a
solve at the family's first v from the sharp shape's profile (`-pf_start sharp`), then
`pf.continuation` in v down to V_MIN and, for a family that starts inside the range, up to
V_MAX, every point with its energy E, the level set's own Canham-Helfrich energy (the
sharp-limit estimate), multipliers, stability index on the constraints' tangent space,
topology and the events: a fold, an index change without one (a bifurcation), a topology
change. A continuation ends at the range, after STEPS points, after
`branching.OTHER_TOPOLOGY` points of a topology without a level-set energy (several
spheres: `branching.topology_lost`), or where its corrector fails.

The phase diagram: at each c0 the least level-set energy over the branches, on a grid of v
(linear interpolation between the points of a stretch of one topology), its regions, the
v where the least-energy family changes (the crossing of the two energies) and where each
branch ends. Writes OUT/branches.md (a table per branch), OUT/diagram.md (regions,
transitions, ends, time per point), OUT/atlas.json (everything the figures need) and, by
`--plot` too, OUT/energy.png (E level set against v per c0) and OUT/diagram.png (v across,
c0 up, regions coloured and labelled, silhouettes of the least-energy shapes).

Each branch is kept in OUT/branches/<family>_c<c0>.h5 (`pfmembrane.result.save_branch`:
its points and its description) as soon as it is followed, and a later run reuses it
(unless --force): a run that dies loses only the branch it was on.
The branches are independent: `--groups G` splits the NP ranks into G groups of NP / G, each
following every G-th branch on its own sub-communicator; the tables are the same whatever
the grouping.

`--adapt F --coarse DIR` follows each branch of the atlas DIR again at --eps on that branch's
nodes relocated by CVT for 1 + F max |grad phi_h| over its points (`pf.adapt`), with max-ent
locality --gamma (graded grids want less than uniform ones: runs/pears/README.md),
--floor Q (one locality over the finest nodes, `pf.Grid`'s spacing_floor) and --band W
(the density flat within W of the interfaces, `pf.adapt`'s band). A switched
family does not retrace its route on these nodes: it starts from its coarse branch's last
stable point (index 0), by Newton alone, and is followed both ways in v.

`--merge` draws one diagram from several atlases: a family that the diagram's eps does not
resolve (the stomatocyte at eps 0.02 keeps its bud off the axis) is followed at a smaller
eps in an atlas of its own, and its branches replace that family's. Which state is least
is decided on the level-set energies, which estimate the same sharp limit at every eps.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

from pfmembrane import report, series
from pfmembrane.analysis.checks import ENERGETIC
from pfmembrane.analysis.sizing import branch_box
from pfmembrane.cli.runner import UsageError
from pfmembrane.paper import SCENE, paper_spacing
from pfmembrane.result import read_branch, save_branch

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RADIUS = SCENE['radius']
V_MIN, V_MAX = 0.55, 0.95
# name: (branch of the start, half box, first v). The stomatocyte starts where its neck
# is widest (runs/crossings) and is followed both ways. The pear is reached by branch
# switching (SWITCHED): the prolate in the full box, where its up-down antisymmetric modes
# live, down in v to its first index change without a fold (`branching.bifurcation`, a
# pear-shaped point counting as one: `branching.asymmetric`), then along the critical mode.
FAMILIES = {'prolate': ('prolate', True, 0.95), 'oblate': ('oblate', True, 0.95),
            'stomatocyte': ('stomatocyte', False, 0.62), 'pear': ('prolate', False, 0.95)}
SWITCHED = {'pear'}
DEFAULT_FAMILIES = ['prolate', 'oblate', 'stomatocyte']
CURVATURES = [-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5]  # reduced c0 = 2 C0 R
MARGIN = 5.0      # eps between the box and every sharp shape of a branch
BOX_STEP = 0.05
BOX_SAMPLES = 9   # volumes whose sharp shapes size a branch's box
DV = 0.0025       # v grid of the diagram
SPHERE = ENERGETIC[0]  # '1 sphere'
# Defaults of every grid: `pf.Grid`'s (the paper's gamma, no spacing floor), no band.
GAMMA, FLOOR, BAND = 0.8, 0.0, 0.0


def box_of(family, c0, eps):
    """One box for a branch: its family's sharp shapes at BOX_SAMPLES volumes of its range
    (those the sharp solver finds) with MARGIN eps, rounded up to BOX_STEP
    (`sizing.branch_box`)."""
    branch, half, first = FAMILIES[family]
    top = V_MAX if first >= V_MAX else min(V_MAX, first + 0.1)
    try:
        return branch_box(branch, np.linspace(V_MIN, top, BOX_SAMPLES), eps, RADIUS,
                          c0 / (2 * RADIUS), margin=MARGIN, step=BOX_STEP)
    except RuntimeError:
        raise RuntimeError(f"no sharp {branch} shape at c0 = {c0:g} sizes a box") from None


def point(res, wall):
    """What a table row and the diagram keep of a state."""
    a = res.attrs
    return dict(v=float(a['reduced_volume']), E=float(a['energy']),
                level=float(a.get('level_set_energy', math.nan)),
                nu_A=float(a['nu_area']), nu_V=float(a['nu_volume']),
                index=int(a.get('index_0', -1)), topology=str(a.get('topology', 'none')),
                fold=int(a.get('fold', 0)), bifurcation=int(a.get('index_change', 0)),
                its=int(a.get('stage2_iterations', -1)), converged=int(a['converged']),
                wall=wall)


def shown(path):
    """`path` as a page shows it: relative to the repository when inside it."""
    relative = os.path.relpath(os.path.abspath(path), ROOT)
    return path if relative.startswith(os.pardir) else relative


def branch_path(out, family, c0):
    return os.path.join(out, 'branches', f"{family}_c{c0:g}.h5")


def save(path, branch, comm=None):
    """A followed branch to `path`: its states (`shapes`, Results) and the rest of its
    description, in one versioned file written whole or not at all
    (`pfmembrane.result.save_branch`). Collective on `comm` (rank 0's branch is written)."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    save_branch(path, branch['shapes'], comm=comm,
                attrs={k: v for k, v in branch.items() if k != 'shapes'})


def load(path):
    """The branch `save` wrote (`pfmembrane.result.read_branch`; a file of the layout
    before the versioned one too), its `shapes` Results."""
    shapes, branch = read_branch(path)
    return dict(branch, shapes=shapes, box=tuple(branch['box']))


def follow(family, c0, args, comm, say):
    """One branch: the solve at its first v, then the continuations, unless OUT holds
    it (and not --force). Collective on `comm`. Returns its description and points (the
    start, then each continuation's in order), with the nodes and phi of every point."""
    path = branch_path(args.out, family, c0)
    mpi = comm.tompi4py()
    if not args.force and mpi.bcast(os.path.exists(path), root=0):
        say(f"-- {family} c0 {c0:g}: {path} (reused)")
        return load(path)
    branch = trace(family, c0, args, comm, say)
    save(path, branch, mpi)
    return branch


def coarse_branch(out, family, c0):
    """The branch OUT/branches holds, whose points an adapted grid follows."""
    path = branch_path(out, family, c0)
    if not os.path.exists(path):
        raise RuntimeError(f"no coarse branch {path} to adapt to (run the atlas into {out})")
    return load(path)


def trace(family, c0, args, comm, say):
    """`follow`, computed."""
    import pfmembrane as pf
    from pfmembrane.branching import OTHER_TOPOLOGY, asymmetric, bifurcation, topology_lost
    branch, half, first = FAMILIES[family]
    t0 = time.perf_counter()
    basis = dict(gamma=args.gamma, spacing_floor=args.floor)
    described = dict(family=family, c0=c0, eps=args.eps, **basis, half=half,
                     box=(math.nan, math.nan), nodes=0, eps_min=math.nan, points=[], shapes=[])
    try:  # the same on every rank of the group: no collective call is left waiting
        coarse = coarse_branch(args.coarse, family, c0) if args.adapt else None
        box = coarse['box'] if coarse else args.box or box_of(family, c0, args.eps)
        scene = pf.Scene(reduced_volume=first, c0=c0 / (2 * RADIUS), radius=RADIUS,
                         box=box, branch=branch, symmetric=half)
        if coarse:
            along = coarse['shapes']
            grid = pf.adapt(along[0], args.adapt, comm=comm, along=along[1:], band=args.band,
                            **basis)
            say(grid.adapt_summary())
        else:
            grid = pf.Grid.uniform(scene, nodes=paper_spacing(args.nodes, box), comm=comm,
                                   **basis)
        say(f"-- {family} c0 {c0:g}: box {box[0]:g}x{box[1]:g}{' (half)' if half else ''}, "
            f"{grid!r}")
        t1 = time.perf_counter()
        # the route to a switched branch is not on nodes adapted to the branch: it starts
        # from the coarse branch's last stable point, by Newton alone (its first point, next
        # to the bifurcation, can fall back to the branch it left at a smaller eps)
        resumed = bool(coarse) and family in SWITCHED
        if resumed:
            k = last_stable(coarse['points'])
            start = pf.solve(along[k].scene, grid, args.eps, start=along[k],
                             options=dict(args.solver, pf_stage1='none'), checks=True)
        else:
            start = pf.solve(scene, grid, args.eps, options=dict(args.solver, pf_start='sharp'), checks=True)
    except (RuntimeError, UsageError) as e:
        say(f"-- {family} c0 {c0:g}: no start ({e})")
        return dict(described, ends=[f"no start ({e})"], time=time.perf_counter() - t0)
    switch, jumped = family in SWITCHED and not resumed, False
    where = start.attrs['reduced_volume']
    if switch and start.converged:
        start, where, jumped = bifurcation(
            start, 'reduced_volume', -args.ds, args.steps, V_MIN, options=args.solver,
            say=lambda text: say(f"   {family} c0 {c0:g}: {branch} {text}"), left=asymmetric)
        if start is None:
            return dict(described, box=box, nodes=grid.n_nodes, eps_min=grid.eps_min,
                        ends=[f"no index change without a fold on the full-box {branch} "
                              f"down to v {where:.4f}"], time=time.perf_counter() - t0)
        say(f"-- {family} c0 {c0:g}: the {branch} branch bifurcates near v {where:.4f}"
            + (f", where its corrector left it for the {family}s" if jumped else ''))
    points = [dict(point(start, time.perf_counter() - t1), arclength=0.0, direction=0)]
    # the start as it is now: the continuations give its attrs their index_0 after
    shapes = [pf.Result(start.nodes, start.phi, dict(start.attrs))]
    ends = [f"started where the {branch}'s corrector left it at v {where:.4f}"] if jumped else []
    if resumed:
        ends.append(f"started from the last stable point of {args.coarse}'s branch at v {where:.4f}"
                    + ('' if asymmetric(start) else ', which came back up-down symmetric'))
    switched = switch and not jumped
    if not start.converged:
        ends.append(f"the start at v {where:g} did not converge ({start.message})")
    # a switched branch's two sides are mirror images: one is followed; a branch the
    # corrector landed on, onward from there
    if switch:
        directions = [1] if switched else [int(math.copysign(1, start.attrs['dp_ds']))]
    else:
        directions = [d for d, go in ((-1, where > V_MIN), (1, where < V_MAX)) if go]

    def way(direction, v):  # where the corrector landed, the tangent's sign is not v's
        return 'down' if (v < points[0]['v'] if jumped else direction < 0) else 'up'

    for direction in directions if start.converged else []:
        last, stretch = time.perf_counter(), []
        for res in pf.continuation(start, 'reduced_volume', direction * args.ds, args.steps,
                                   options=args.solver, switch=switched, checks=True):
            now = time.perf_counter()
            p = dict(point(res, now - last), arclength=res.attrs['arclength'],
                     direction=direction)
            last = now
            stretch.append((p, pf.Result(res.nodes, res.phi, dict(res.attrs))))
            say(f"   {family} c0 {c0:g}: v {p['v']:.4f} E {p['E']:.6f} level {p['level']:.6f} "
                f"index {p['index']} {p['topology']} its {p['its']} {p['wall']:.2f} s")
            if not V_MIN - 1e-9 <= p['v'] <= V_MAX + 1e-9:
                ends.append(f"{way(direction, p['v'])}: left the range at v {p['v']:.4f}")
                break
            if topology_lost([q['topology'] for q, _ in stretch]):
                ends.append(f"{way(direction, p['v'])}: {p['topology']} at v {p['v']:.4f}, "
                            f"{OTHER_TOPOLOGY} points without a level-set energy")
                break
        else:
            v_end = stretch[-1][0]['v'] if stretch else points[0]['v']
            ends.append(f"{way(direction, v_end)}: stopped at v {v_end:.4f} "
                        f"({'after ' + str(args.steps) + ' points' if len(stretch) == args.steps else 'the corrector failed'})")
        points += [p for p, _ in stretch]
        shapes += [s for _, s in stretch]
    points[0]['index'] = int(start.attrs.get('index_0', -1))  # set by the first continuation
    return dict(described, box=box, nodes=grid.n_nodes, eps_min=grid.eps_min, points=points,
                ends=ends, shapes=shapes, time=time.perf_counter() - t0,
                bifurcation_v=where if switch else math.nan)


def last_stable(points):
    """The index of the last of a branch's points with stability index 0 (0 if none)."""
    return max((i for i, p in enumerate(points) if p['index'] == 0), default=0)


def paths(points):
    """A branch's continuations in the order they went, each from the start (the
    points: the start, then each direction's in order)."""
    return [points[:1] + [p for p in points if p['direction'] == d]
            for d in dict.fromkeys(p['direction'] for p in points[1:])] or [points[:1]]


def events(points):
    """Per point, the events since the point before it on its continuation."""
    out, before = [], {}
    for p in points:
        e, last = [], before.get(p['direction'], points[0] if p['direction'] else None)
        before[p['direction']] = p
        if p['fold']:
            e.append('fold')
        if p['bifurcation']:
            e.append('index change')
        if last is not None and last['topology'] != p['topology']:
            e.append(f"topology {last['topology']} -> {p['topology']}")
        out.append(', '.join(e))
    return out


HEADER = ('| v | E | E level set | nu_A | nu_V | index | topology | events | converged | its '
          '| s | arclength |')


def table(branch):
    rows = [HEADER, '|' + '---|' * (HEADER.count('|') - 1)]
    for p, e in zip(branch['points'], events(branch['points'])):
        rows.append(f"| {p['v']:.4f} | {p['E']:.6f} | {p['level']:.6f} | {p['nu_A']:.4f} "
                    f"| {p['nu_V']:.3f} | {p['index']} | {p['topology']} | {e} "
                    f"| {p['converged']} | {p['its']} "
                    f"| {p['wall']:.2f} | {p['direction'] * p['arclength']:+.4f} |")
    return rows


def stretches(points):
    """Runs of consecutive points of one continuation, one topology and finite
    level-set energies."""
    runs = []
    for path in paths(points):
        current = []
        for p in path:
            if current and (p['topology'] != current[-1]['topology']
                            or not math.isfinite(p['level'])):
                runs.append(current)
                current = []
            if math.isfinite(p['level']):
                current.append(p)
        runs.append(current)
    return [r for r in runs if len(r) > 1]


def label(family, topology):
    return family if topology == SPHERE else f"{family} ({topology})"


def least(branches, c0, vs):
    """At each v of `vs`: (label, level-set energy) of the least over the branches at c0,
    ('', nan) where none reaches."""
    best = [('', math.inf)] * len(vs)
    for b in (b for b in branches if b['c0'] == c0):
        for run in stretches(b['points']):
            v = np.array([p['v'] for p in run])
            e = np.array([p['level'] for p in run])
            for i, x in enumerate(vs):
                for j in range(len(v) - 1):  # every piece over x: a fold has two
                    lo, hi = sorted((v[j], v[j + 1]))
                    if lo <= x <= hi and hi > lo:
                        y = e[j] + (e[j + 1] - e[j]) * (x - v[j]) / (v[j + 1] - v[j])
                        if y < best[i][1]:
                            best[i] = (label(b['family'], run[0]['topology']), y)
    return [(name, y if math.isfinite(y) else math.nan) for name, y in best]


def grid_v():
    return np.round(np.arange(V_MIN, V_MAX + DV / 2, DV), 6)


def transitions(best, vs):
    """(v, below, above) where the least-energy label changes along v."""
    return [(0.5 * (vs[i] + vs[i + 1]), best[i][0], best[i + 1][0])
            for i in range(len(vs) - 1) if best[i][0] != best[i + 1][0]]


def write(branches, args, out, wall, record=None):
    """OUT/branches.md, and by `diagram` the phase diagram, under the provenance `record`
    (`report.provenance`, taken at the start of the run; now by default). Not collective."""
    record = record or report.provenance()
    grids = (f"the nodes of the branches of {args.coarse} relocated by CVT for 1 + "
             f"{args.adapt:g} max |grad phi_h| over each branch's points"
             + (f" (and within {args.band:g} of them)" if args.band else '') if args.adapt else
             f"uniform grids of the spacing of {args.nodes} nodes in the paper box")
    floor = f" (spacing floored at its {args.floor:g}-quantile)" if args.floor else ''
    head = (f"eps {args.eps:g}, {grids}, max-ent gamma {args.gamma:g}{floor}, R = {RADIUS:g}, "
            f"k = 1; {args.np} MPI ranks in "
            f"{args.groups} group(s) on {os.cpu_count()} cores.")
    command = (f"`python runs/atlas/atlas.py --np {args.np} --groups {args.groups} "
               f"--eps {args.eps:g}" + ('' if args.adapt else f" --nodes {args.nodes}")
               + f" --ds {args.ds:g} --steps {args.steps}"
               f" --families {' '.join(args.families)} --c0 {' '.join(map(format, args.c0))}"
               + (f" --box {args.box[0]:g},{args.box[1]:g}" if args.box else '')
               + (f" --adapt {args.adapt:g} --coarse {args.coarse}" if args.adapt else '')
               + (f" --band {args.band:g}" if args.band else '')
               + (f" --gamma {args.gamma:g}" if args.gamma != GAMMA else '')
               + (f" --floor {args.floor:g}" if args.floor else '')
               + f" --out {shown(args.out)}`")
    lines = [*report.header("Branches of the shape atlas", record), head + "\n", f"Regenerate: {command}.\n",
             "E level set: the Canham-Helfrich energy of phi_h = 0 (the sharp-limit estimate; "
             "nan where it is not one sphere or torus); index: negative eigenvalues of the "
             "Hessian of the Lagrangian on the constraints' tangent space (the bordered "
             "factorization's inertia); events: since the point before on the same continuation; "
             "arclength: signed, negative down in v from the first point.\n"]
    for b in branches:
        pts = b['points']
        lines += [f"\n## {b['family']}, c0 = {b['c0']:g}\n",
                  f"Box {b['box'][0]:g} x {b['box'][1]:g}{' (half box)' if b['half'] else ''}, "
                  f"{b['nodes']} nodes (eps_min {b['eps_min']:.4g}); {len(pts)} points in "
                  f"{b['time']:.1f} s; median step {median_step(b):.2f} s. "
                  f"Ends: {'; '.join(b['ends']) or 'none'}.\n"] + table(b)
    report.write(os.path.join(out, 'branches.md'), lines)
    points = sum(len(b['points']) for b in branches)
    computed = sum(b['time'] for b in branches)
    footer = (f"{points} points on {len(branches)} branches: {computed:.0f} s of branch "
              f"time on groups of {args.np // args.groups} rank(s), "
              f"{computed / max(points, 1):.2f} s per point; the median continuation step "
              f"{np.nanmedian([median_step(b) for b in branches]):.2f} s. This invocation: "
              f"{wall:.0f} s wall on {args.np} ranks (branches it reused cost it nothing).")
    diagram(branches, head, command, footer, silhouettes(branches), out,
            dict(eps=args.eps, nodes=args.nodes, np=args.np), record)


def diagram(branches, head, command, footer, pictures, out, about, record=None):
    """OUT/diagram.md (under the provenance `record`, now by default), OUT/atlas.json
    (`about` the run, the branches without their shapes, the silhouettes `pictures`:
    everything the figures need) and the figures. Not collective."""
    record = record or report.provenance()
    branches = [{k: v for k, v in b.items() if k != 'shapes'} for b in branches]
    vs = grid_v()
    lines = [*report.header("The phase diagram of the spontaneous-curvature model", record),
             head + "\n",
             f"Regenerate: {command}.\n",
             "At each c0 (reduced, 2 C0 R) the state of least level-set energy over the "
             f"branches on a grid of v spaced {DV:g}; transitions: the v between two grid "
             "volumes where it changes (to within the grid spacing); ends: where each branch "
             "stopped, and its folds (the index across each). SBL at c0 = 0: prolate above 0.652, oblate down to 0.592, "
             "stomatocyte below.\n",
             "| c0 | regions (v from high to low) | transitions v | ends |", "|---|---|---|---|"]
    for c0 in sorted({b['c0'] for b in branches}):
        best = least(branches, c0, vs)
        regions = []
        for i in range(len(vs) - 1, -1, -1):
            if i == len(vs) - 1 or best[i][0] != best[i + 1][0]:
                regions.append([best[i][0] or 'none', vs[i], vs[i]])
            regions[-1][2] = vs[i]
        text = '; '.join(f"{n} {lo:.4f}-{hi:.4f}" for n, hi, lo in regions)
        trans = ', '.join(f"{v:.4f} ({a or 'none'} / {b or 'none'})"
                          for v, a, b in transitions(best, vs))
        ends = '; '.join(f"{b['family']}: {', '.join(b['ends'] + folds(b))}" for b in branches
                         if b['c0'] == c0)
        lines.append(f"| {c0:g} | {text} | {trans} | {ends} |")
    with open(os.path.join(out, 'diagram.md'), 'w') as f:
        f.write('\n'.join(lines + ["", footer]) + '\n')
    with open(os.path.join(out, 'atlas.json'), 'w') as f:
        json.dump(dict(args=about, branches=branches, silhouettes=pictures), f, indent=1)
    plot(out)


def merge(sources, out, record=None):
    """One phase diagram of the branches of several atlases (SOURCE/atlas.json each): a
    family at a c0 that a later source followed too is the later one's (a family resolved
    at a smaller eps, say). Each region's silhouette comes from the branch files where the
    sources still hold them, else from the sources' own silhouettes. `record`: as
    `diagram`'s. Not collective."""
    record = record or report.provenance()
    kept, pictures = {}, {}
    for source in sources:
        with open(os.path.join(source, 'atlas.json')) as f:
            data = json.load(f)
        for b in data['branches']:
            path = branch_path(source, b['family'], b['c0'])
            b = load(path) if os.path.exists(path) else dict(b, shapes=[])
            b.setdefault('eps', data['args']['eps'])  # atlases written before eps per branch
            kept[b['family'], b['c0']] = b
            pictures[b['family'], b['c0']] = [s for s in data['silhouettes'] if s['c0'] == b['c0']
                                              and s['label'].split(' ')[0] == b['family']]
    branches = list(kept.values())
    os.makedirs(out, exist_ok=True)
    shapes = silhouettes(branches)
    for c0 in sorted({b['c0'] for b in branches}):
        drawn = {s['label'] for s in shapes if s['c0'] == c0}
        have = [s for (_, c), ss in pictures.items() if c == c0 for s in ss]
        for name, mid in middles(branches, c0):
            near = [s for s in have if s['label'] == name]
            if name not in drawn and near:
                shapes.append(min(near, key=lambda s: abs(s['v'] - mid)))
    at = {}  # eps: family: c0s
    for b in branches:
        at.setdefault(b['eps'], {}).setdefault(b['family'], []).append(b['c0'])
    head = (f"The branches of {', '.join(sources)} (their branches.md); "
            + '; '.join(f"eps {e:g}: " + ', '.join(f"{f} at c0 {', '.join(f'{c:g}' for c in c0s)}"
                                                   for f, c0s in families.items())
                        for e, families in sorted(at.items(), reverse=True)) + '.')
    footer = (f"{sum(len(b['points']) for b in branches)} points on {len(branches)} branches; "
              f"their times are in each source's diagram.md.")
    diagram(branches, head, f"`python runs/atlas/atlas.py --merge {' '.join(sources)} "
            f"--out {shown(out)}`", footer, shapes, out, dict(eps=min(at), merged=sources), record)


def folds(branch):
    """The folds of a branch, as text: where its continuations turned back in v."""
    return [f"fold at v {turning_v(path, k):.4f} (index {path[k - 1]['index']} -> "
            f"{path[k]['index']})"
            for path in paths(branch['points']) for k in range(1, len(path))
            if path[k]['fold']]


def turning_v(path, k):
    """The v where a path turns, between its points k - 1 and k (the first past the turn):
    the vertex of the parabola v(s) through three points around it, which the step
    lengths move less than the points themselves (none beyond them)."""
    near = path[max(0, min(k - 2, len(path) - 3)):][:3]
    v = np.array([p['v'] for p in near])
    if len(near) < 3:
        return float(v[-1])
    s = np.array([p['arclength'] for p in near])
    a, b, c = np.polyfit(s, v, 2)
    if a and s.min() <= -b / (2 * a) <= s.max():
        return float(c - b * b / (4 * a))
    return float(v.max() if a < 0 else v.min())


def median_step(branch):
    steps = [p['wall'] for p in branch['points'] if p['direction']]
    return float(np.median(steps)) if steps else math.nan


def middles(branches, c0):
    """(label, v) of each region of the least-energy state at c0 and the grid volume in
    its middle."""
    vs = grid_v()
    best = least(branches, c0, vs)
    for name in dict.fromkeys(n for n, _ in best if n):
        where = [vs[i] for i, (n, _) in enumerate(best) if n == name]
        yield name, where[len(where) // 2]


def silhouettes(branches):
    """The level set of the least-energy state nearest the middle of each region of each
    c0, as (c0, v, label, [[r...], [z...]] per piece) about its centroid."""
    from pfmembrane.analysis import levelset
    out = []
    for c0 in sorted({b['c0'] for b in branches}):
        for name, mid in middles(branches, c0):
            candidates = [(abs(p['v'] - mid), b, i) for b in branches
                          if b['c0'] == c0 and b['shapes'] for i, p in enumerate(b['points'])
                          if label(b['family'], p['topology']) == name]
            if not candidates:  # branches read from atlas.json alone (`merge`)
                continue
            _, b, i = min(candidates, key=lambda t: t[0])
            shape = b['shapes'][i]
            try:
                curve = levelset.level_set(shape.checkpoint().unfolded())
            except (ValueError, RuntimeError):
                continue
            zc = 0.5 * float(shape.attrs['box'][1])
            out.append(dict(c0=c0, v=b['points'][i]['v'], label=name,
                            pieces=[[c[:, 0].tolist(), (c[:, 1] - zc).tolist()]
                                    for c in curve]))
    return out


COLOURS = {'prolate': '#4c72b0', 'oblate': '#dd8452', 'stomatocyte': '#55a868',
           'pear': '#c44e52'}


def plot(out):
    """OUT/energy.png and OUT/diagram.png from OUT/atlas.json. Not collective."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    with open(os.path.join(out, 'atlas.json')) as f:
        data = json.load(f)
    branches = data['branches']
    curvatures = sorted({b['c0'] for b in branches})
    cols = min(4, len(curvatures))
    rows = math.ceil(len(curvatures) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 3.2 * rows), squeeze=False)
    for ax, c0 in zip(axes.flat, curvatures):
        for b in (b for b in branches if b['c0'] == c0):
            for run in stretches(b['points']):
                ax.plot([p['v'] for p in run], [p['level'] for p in run], '-',
                        color=COLOURS.get(b['family'], 'k'),
                        label=label(b['family'], run[0]['topology']))
        ax.set_title(f"c0 = {c0:g}")
        ax.set_xlabel('v')
        ax.set_ylabel('E level set')
        ax.legend(fontsize=6)
    for ax in list(axes.flat)[len(curvatures):]:
        ax.set_visible(False)
    fig.tight_layout()
    fig.savefig(os.path.join(out, 'energy.png'), dpi=120)
    plt.close(fig)

    vs = grid_v()
    fig, ax = plt.subplots(figsize=(9, 7))
    step = np.diff(curvatures).min() if len(curvatures) > 1 else 1.0
    names = []
    for c0 in curvatures:
        best = least(branches, c0, vs)
        for i, (name, _) in enumerate(best):
            if not name:
                continue
            family = name.split(' ')[0]
            if name not in names:
                names.append(name)
            ax.add_patch(matplotlib.patches.Rectangle(
                (vs[i] - DV / 2, c0 - step / 2), DV, step, linewidth=0,
                facecolor=COLOURS.get(family, '0.7'), alpha=0.35 if name == family else 0.6))
        for v, a, b in transitions(best, vs):
            ax.plot(v, c0, 'k|', markersize=12)
    for b in branches:  # where a switched family left the branch it bifurcates from
        if math.isfinite(b.get('bifurcation_v', math.nan)):
            ax.plot(b['bifurcation_v'], b['c0'], '*', color=COLOURS.get(b['family'], 'k'),
                    markersize=11, markeredgecolor='k')
    ax.set_xlim(V_MIN - DV, V_MAX + DV)
    ax.set_ylim(curvatures[0] - step / 2, curvatures[-1] + step / 2)
    # silhouettes at one scale in both directions: R spans 0.15 of a row
    box = ax.get_window_extent()
    per_c0 = box.height / np.ptp(ax.get_ylim())
    per_v = box.width / np.ptp(ax.get_xlim())
    zscale = 0.15 * step / RADIUS
    rscale = zscale * per_c0 / per_v
    for s in data['silhouettes']:
        for r, z in s['pieces']:
            r, z = np.asarray(r), np.asarray(z)
            for side in (1, -1):  # the meridian and its mirror image across the axis
                ax.plot(s['v'] + side * rscale * r, s['c0'] + zscale * z, 'k-', linewidth=0.8)
        ax.annotate(s['label'], (s['v'], s['c0'] - 0.45 * step), ha='center', fontsize=7)
    ax.set_xlabel('reduced volume v')
    ax.set_ylabel('reduced spontaneous curvature c0 = 2 C0 R')
    eps = sorted({b.get('eps', data['args']['eps']) for b in branches}, reverse=True)
    ax.set_title(f"least level-set energy (phase fields, eps {', '.join(f'{e:g}' for e in eps)}"
                 + (', per branch in diagram.md' if len(eps) > 1 else '') + '); | transitions'
                 + ('; * bifurcations' if any(math.isfinite(b.get('bifurcation_v', math.nan))
                                              for b in branches) else ''))
    fig.savefig(os.path.join(out, 'diagram.png'), dpi=130, bbox_inches='tight')
    plt.close(fig)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    record = report.provenance()  # before anything is measured
    ap = argparse.ArgumentParser(prog='python runs/atlas/atlas.py',
                                 description=__doc__.splitlines()[0])
    series.group_arguments(ap, 'branch')
    series.grid_arguments(ap, 0.02, 40000, "branch (default: its family's sharp shapes')")
    ap.add_argument('--families', nargs='+', default=DEFAULT_FAMILIES, choices=list(FAMILIES))
    ap.add_argument('--c0', type=float, nargs='+', default=CURVATURES,
                    help='reduced spontaneous curvatures 2 C0 R')
    ap.add_argument('--ds', type=float, default=0.05, help='first arclength step')
    ap.add_argument('--steps', type=int, default=120, help='most points per continuation')
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'atlas'))
    ap.add_argument('--adapt', type=float, metavar='F',
                    help='follow each branch on the nodes of its branch in --coarse, relocated '
                         'by CVT for 1 + F max |grad phi_h| over its points')
    ap.add_argument('--coarse', metavar='DIR', help='the atlas whose branches --adapt follows')
    ap.add_argument('--band', type=float, default=BAND, metavar='W',
                    help='width w: the CVT density takes the largest |grad phi_h| within w, so '
                         'the nodes are evenly spaced across the interface (0: none), of --adapt')
    ap.add_argument('--gamma', type=float, default=GAMMA,
                    help='max-ent locality gamma (beta_a = gamma / h_a^2) of every grid; graded '
                         'grids want less than uniform ones (runs/pears/README.md)')
    ap.add_argument('--floor', type=float, default=FLOOR, metavar='Q',
                    help='quantile Q of the smoothed h_a below which beta_a stays gamma / h_Q^2: '
                         'one locality over the finest nodes of a graded grid (0: none), of '
                         'every grid')
    ap.add_argument('--force', action='store_true',
                    help='follow every branch again, even one OUT/branches holds')
    ap.add_argument('--plot', metavar='OUT', help='redraw the figures of OUT/atlas.json')
    ap.add_argument('--merge', metavar='SOURCE', nargs='+',
                    help="one diagram in --out of these atlases' branches, a family at a c0 "
                         "from the last source that has it")
    args = series.parsed(ap, argv)
    if bool(args.adapt) != bool(args.coarse):
        ap.error('--adapt and --coarse go together')
    if args.band and not args.adapt:
        ap.error('--band needs --adapt')
    if args.plot:
        plot(args.plot)
        return 0
    if args.merge:
        merge(args.merge, args.out, record)
        print(os.path.join(args.out, 'diagram.md'))
        return 0
    todo = [(f, c0) for c0 in args.c0 for f in args.families]
    t0 = time.perf_counter()
    branches = series.on_groups(args.np, args.groups, __file__, todo,
                                lambda piece, comm, say: follow(*piece, args, comm, say))
    if branches is not None:
        os.makedirs(args.out, exist_ok=True)
        write(branches, args, args.out, time.perf_counter() - t0, record)
        print(os.path.join(args.out, 'diagram.md'))
    return 0


if __name__ == '__main__':
    sys.exit(main())
