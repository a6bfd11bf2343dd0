"""The sharp phase diagram of the spontaneous-curvature model, one c0 row at a time: every
axisymmetric branch followed in v by the solver's own minimization, the least energy on a v
grid, its regions and the transitions between them solved to 1e-10 in v.

It lives in the subpackage because it continues branches point by point with the solver's
private pieces (`solver._minimize`, `_Grid`, `_start`, `_refined`, `_tail`, `_is_branch`,
`_evaluate`, `_embedded_prolate`), which `sharp.solve` (a continuation from the sphere per
call) does not expose; `row` returns plain data, so scripts (runs/sharp_diagram/diagram.py)
need no more than it.

    from pfmembrane.sharp import diagram
    result = diagram.row(0.0, radius=R)     # result['regions'], result['transitions'], ...

c0 mapping. c0 is the phase-field scene's reduced spontaneous curvature 2 C0 R: the sharp
reference of a scene of radius R is `sharp.solve(v, branch, c0=c0_sharp, radius=R)` with
c0_sharp = c0 / (2 R) (as `analysis.levelset.reference` calls it), whose energy depends on
C0 R = c0 / 2 and k alone. This module works in the solver's unit R0 = 1, k = 1 with
C0 R0 = c0 / 2, which gives the same energies; R enters only as the unit of the C0 handed to
`solver.pear_mode`.

Branch following. Per row, every branch is followed in v on the grid V_MAX, V_MAX - DV, ...
down to V_MIN (up as well for the branches that start inside the range), each point from the
previous one (the secant prediction of the last two) by the solver's feasible-path
Newton-Lagrange minimization (`solver._minimize`), its resolution doubled while the top
quarter of the sine spectrum is above `solver.TAIL`, as `solve` does.

Step halving and branch ends. A step that fails, leaves the branch (`solver._is_branch` and
the shape tests of `_why_not`) or lands on a shape far from the previous one (a point of the
curve, at the same fraction of its length, moved by more than JUMP R: a jump to another
branch) is halved, down to DV / 16; the branch ends there and the row says why, from the last
point's shape (neck, gap between the dimples, spectrum) and the least eigenvalue of the
second variation on the constraints' tangent space (towards zero: a fold, located by a
linear fit of its square in v).

Branches. Prolate and oblate (up-down symmetric, the solver's starts at v 0.95, C0 ramped at
v 0.95); stomatocyte (general path, the solver's start at v 0.5, C0 = 0, moved to v 0.6 (or
0.55 if the ramp fails at 0.6), C0 ramped there, then followed both ways); pear (branch
switching off the prolate: the zero in v of `solver.pear_mode`, the prolate's least up-down
antisymmetric second variation, by brentq; the prolate there plus a little of its mode,
minimized on all modes, followed both ways unless it is a point of a branch already
followed); at c0 in NECK_ROWS the narrow-neck branches, started from two spheres joined by a
smoothed neck: the neck pear (R1 > R2, all modes, started at v 0.74) and the neck dumbbell
(equal spheres, even modes, started at v 0.70), both followed both ways.

Regions and transitions. The least energy on the v grid gives the regions; where it changes,
the energy difference of the two branches is solved to 1e-10 in v by brentq crossings (each
energy a warm-started minimization from the branch's nearest point); where a branch ends
between two grid points the change is reported at its end.
"""
import math
import time
import warnings

import numpy as np
from scipy.linalg import null_space
from scipy.optimize import brentq

from pfmembrane.sharp import solver as core   # the solver's continuation pieces

__all__ = ['DV', 'JUMP', 'NECK_ROWS', 'V_MAX', 'V_MIN', 'row']

V_MAX, V_MIN, DV = 0.95, 0.55, 0.005
JUMP = 0.1            # R: largest move of a point of the curve between neighbouring points
C_STEP = 0.05         # C0 R0 per step of a ramp in C0
SAMPLES = np.linspace(0.0, np.pi, 401)
NECK_ROWS = (2.5,)    # the c0 rows where the narrow-neck branches are followed
MAX_N = {'prolate': 128, 'oblate': 128, 'stomatocyte': 256, 'pear': 256,
         'neck pear': 256, 'neck dumbbell': 256}
START_N = {'prolate': 32, 'oblate': 32, 'stomatocyte': 64, 'pear': 32,
           'neck pear': 128, 'neck dumbbell': 128}
ASYMMETRIC = 1e-4     # norm of the odd sine modes below which a shape counts as symmetric


# --- shapes ---------------------------------------------------------------------------------

def _targets(grid, v):
    """Area, volume (and closure) of unit R0 at reduced volume v."""
    return np.array([4 * np.pi, v * 4 * np.pi / 3, 0.0][:grid.n_constraints])


def _asymmetry(grid, x):
    """Norm of the odd (up-down antisymmetric) sine modes; 0 on the symmetric grid."""
    return 0.0 if grid.symmetric else float(np.linalg.norm(x[:-1][grid.modes % 2 == 1]))


def _geometry(grid, x):
    """(neck, gap): the narrowest interior waist of r (nan without one) and z(pi) - z(0),
    the distance between the poles along the axis (the dimples' gap on an oblate)."""
    _, r, z = grid.curve(x, SAMPLES)
    inner = np.flatnonzero((r[1:-1] < r[:-2]) & (r[1:-1] <= r[2:])) + 1
    neck = float(r[inner].min()) if inner.size else math.nan
    return neck, float(z[-1] - z[0])


def _why_not(kind, grid, x):
    """None if x has the shape of branch `kind`, else what it has become."""
    _, r, z = grid.curve(x, grid.output)
    height, width = np.ptp(z), 2 * np.max(r)
    if kind in ('prolate', 'pear', 'neck pear', 'neck dumbbell') and height <= width:
        return 'no longer prolate (height <= width)'
    if kind == 'pear' and _asymmetry(grid, x) < ASYMMETRIC:
        return 'back on the symmetric prolate (odd modes vanish)'
    if kind in ('oblate', 'stomatocyte') and z[-1] <= z[0]:
        return ('the dimples touch (the poles pass through each other on the axis)'
                if kind == 'oblate' else 'the inner pole reaches the outer one')
    if kind in ('oblate', 'stomatocyte') and not core._is_branch(grid, x, kind):
        return ('no longer oblate (height >= width)' if kind == 'oblate'
                else 'no longer a stomatocyte (up-down symmetric)')
    return None


def _settle(kind, grid, x, v, c):
    """Minimum near x at (v, C0 R0 = c) still of branch `kind`, the resolution doubled up to
    MAX_N while the spectrum is unresolved: (grid, x, multipliers)."""
    x, multipliers = core._minimize(grid, x, _targets(grid, v), c)
    while core._tail(grid, x) > core.TAIL and grid.n < MAX_N[kind]:
        grid, x = core._refined(grid, x)
        x, multipliers = core._minimize(grid, x, _targets(grid, v), c)
    problem = _why_not(kind, grid, x)
    if problem:
        raise RuntimeError(problem)
    return grid, x, multipliers


def _least_eigenvalues(grid, x, c, multipliers):
    """Least eigenvalue of the second variation on the tangent space of the constraints, over
    all modes of the grid and (symmetric grid) over the odd modes of the same shape on the
    grid of all modes (the pear mode): (least, least antisymmetric or nan)."""
    def spectrum(g, y, mu):
        _, gradients = core._evaluate(g, y, c)
        Z = null_space(gradients[1:])
        H = g.hessians(y, c)
        values, vectors = np.linalg.eigh(Z.T @ (H[0] - np.tensordot(mu, H[1:], axes=1)) @ Z)
        return values, Z @ vectors
    values, _ = spectrum(grid, x, multipliers)
    if not grid.symmetric:
        return float(values[0]), math.nan
    full = core._Grid(grid.n, False)
    y = np.zeros(full.modes.size + 1)
    y[:-1][full.modes % 2 == 0], y[-1] = x[:-1], x[-1]
    _, gradients = core._evaluate(full, y, c)
    mu = np.linalg.lstsq(gradients[1:].T, gradients[0], rcond=None)[0]
    anti_values, vectors = spectrum(full, y, mu)
    odd = np.append(full.modes % 2 == 1, False)
    anti = np.flatnonzero((vectors[odd] ** 2).sum(axis=0) > 0.5)
    return float(values[0]), float(anti_values[anti[0]])


def _two_spheres(grid, v, width=0.04):
    """Variables of two spheres R1 >= R2 (R1^2 + R2^2 = 1, R1^3 + R2^3 = v, v at least
    2^-1/2 + 1e-4) joined by a neck smoothed over `width` in theta: the tangent angle rises
    0 -> pi on the first, falls back to 0 at the neck and rises 0 -> pi on the second."""
    v = max(v, 2 ** -0.5 + 1e-4)
    R2 = brentq(lambda R2: (1 - R2 ** 2) ** 1.5 + R2 ** 3 - v, 1e-6, np.sqrt(0.5))
    R1 = np.sqrt(1 - R2 ** 2)
    length = R1 + R2
    s = grid.theta * length
    neck = 0.5 * (1 + np.tanh((grid.theta - np.pi * R1 / length) / width))
    psi = (1 - neck) * s / R1 + neck * (s - np.pi * R1) / R2
    x = np.zeros(grid.modes.size + 1)
    x[:-1] = np.linalg.lstsq(grid.S, psi - grid.theta, rcond=None)[0]
    x[-1] = length
    return x


# --- continuation ---------------------------------------------------------------------------

class _Branch:
    """One branch at one c0: its points in the order followed, their solver states (kept for
    the root-finding, not written), how each end was reached."""

    def __init__(self, kind, c, v_min=V_MIN, v_max=V_MAX):
        self.kind, self.c, self.v_min, self.v_max = kind, c, v_min, v_max
        self.points, self.states = [], []
        self.ends, self.start = [], ''

    def add(self, grid, x, multipliers, v, on_grid):
        values = core._evaluate(grid, x, self.c)[0]
        neck, gap = _geometry(grid, x)
        lam, anti = _least_eigenvalues(grid, x, self.c, multipliers)
        self.points.append(dict(v=v, E=float(values[0]), tension=float(multipliers[0]),
                                pressure=float(multipliers[1]), n=grid.n, neck=neck, gap=gap,
                                asymmetry=_asymmetry(grid, x), eigenvalue=lam,
                                antisymmetric=anti, on_grid=on_grid))
        self.states.append((grid, x))

    def sorted(self):
        order = np.argsort([p['v'] for p in self.points])
        return [self.points[i] for i in order], [self.states[i] for i in order]


def _grid_index(v):
    """Position of v on the v grid: 0 at V_MAX, 1 per DV down, fractional between."""
    return (V_MAX - v) / DV


def _follow(branch, grid, x, multipliers, v, direction, record_first=True):
    """Continue `branch` from the minimum x at v in v (direction -1 down, +1 up) over the
    v grid, within the branch's [v_min, v_max]; records its end. Each step starts from the
    secant prediction of the last two points (from the last point after a failure)."""
    if record_first:
        branch.add(grid, x, multipliers, v, abs(_grid_index(v) - round(_grid_index(v))) < 1e-6)
    h, h_min = DV, DV / 16
    curve = np.array(grid.curve(x, SAMPLES)[1:])
    previous = None      # (v, x) of the point before, on the same grid
    while True:
        k = _grid_index(v)
        target_k = math.floor(k + 1e-6) + 1 if direction < 0 else math.ceil(k - 1e-6) - 1
        target = round(V_MAX - target_k * DV, 10)
        if target < branch.v_min - 1e-9 or target > branch.v_max + 1e-9:
            branch.ends.append(dict(direction=direction, v=v, reason='the range'))
            return
        step = min(h, abs(target - v))
        trial_v = target if step == abs(target - v) else v + direction * step
        start = x
        if previous is not None and previous[1].size == x.size:
            start = x + (x - previous[1]) * (trial_v - v) / (v - previous[0])
        try:
            try:
                g, y, mu = _settle(branch.kind, grid, start, trial_v, branch.c)
            except (RuntimeError, np.linalg.LinAlgError, ValueError):
                if start is x:
                    raise
                previous = None
                g, y, mu = _settle(branch.kind, grid, x, trial_v, branch.c)
            moved = np.max(np.hypot(*(np.array(g.curve(y, SAMPLES)[1:]) - curve)))
            if moved > JUMP:
                raise RuntimeError(f'a jump: the nearest minimum is another shape (the curve '
                                   f'moved {moved:.2f} R)')
        except (RuntimeError, np.linalg.LinAlgError, ValueError) as error:
            h /= 2
            if h < h_min:
                branch.ends.append(dict(direction=direction, v=v, reason=str(error),
                                        tried=trial_v))
                return
            continue
        previous = (v, x)
        grid, x, multipliers, v = g, y, mu, trial_v
        curve = np.array(grid.curve(x, SAMPLES)[1:])
        branch.add(grid, x, multipliers, v, abs(_grid_index(v) - round(_grid_index(v))) < 1e-6)
        h = min(DV, 2 * h)


def _ramp(kind, grid, x, v, c_from, c_to):
    """Move the minimum x at v from C0 R0 = c_from to c_to in steps of C_STEP, halved on
    failure (down to C_STEP / 16): (grid, x, multipliers)."""
    c, h = c_from, C_STEP
    grid, x, multipliers = _settle(kind, grid, x, v, c)
    while c != c_to:
        trial = c_to if abs(c_to - c) <= h else c + math.copysign(h, c_to - c)
        try:
            grid, x, multipliers = _settle(kind, grid, x, v, trial)
            c, h = trial, min(C_STEP, 2 * h)
        except (RuntimeError, np.linalg.LinAlgError):
            h /= 2
            if h < C_STEP / 16:
                raise RuntimeError(f'the ramp in C0 R0 stopped at {c:.4g} at v {v:g}') from None
    return grid, x, multipliers


def _standard_branch(kind, c, **limits):
    """Prolate or oblate: the solver's start at v 0.95, C0 ramped there, followed down."""
    branch = _Branch(kind, c, **{**limits, 'v_max': V_MAX})
    grid = core._Grid(START_N[kind], True)
    x, v = core._start(grid, kind, V_MAX)
    try:
        grid, x, mu = _ramp(kind, grid, x, v, 0.0, c)
    except RuntimeError as error:
        branch.start = f'no start: {error}'
        return branch
    branch.start = f'the solver start at v {v:g}, C0 R0 ramped 0 -> {c:g}'
    _follow(branch, grid, x, mu, v, -1)
    return branch


def _stomatocyte_branch(c, starts=(0.6, 0.55), **limits):
    """The solver's stomatocyte start (v 0.5, C0 = 0) moved to the first of `starts` where
    the ramp in C0 reaches c, followed down and up."""
    branch = _Branch('stomatocyte', c, **limits)
    failures = []
    for v_start in starts:
        grid = core._Grid(START_N['stomatocyte'], False)
        x, v = core._start(grid, 'stomatocyte', v_start)
        try:
            grid, x, mu = _settle('stomatocyte', grid, x, v, 0.0)
            while v < v_start:
                v = min(v_start, v + 0.025)
                grid, x, mu = _settle('stomatocyte', grid, x, v, 0.0)
            grid, x, mu = _ramp('stomatocyte', grid, x, v, 0.0, c)
            break
        except (RuntimeError, np.linalg.LinAlgError) as error:
            failures.append(str(error))
    else:
        branch.start = 'no start: ' + '; '.join(failures)
        return branch
    branch.start = f'the solver start at v 0.5, C0 = 0, moved to v {v_start:g}, C0 R0 ramped'
    _follow(branch, grid, x, mu, v, -1)
    _follow(branch, grid, x, mu, v, +1, record_first=False)
    return branch


def _pear_point(prolate, c, radius):
    """The pear bifurcation of the prolate: the v where `sharp.pear_mode` changes sign between
    two prolate grid points (brentq to 1e-6), or None."""
    points = [p for p in prolate.sorted()[0] if p['on_grid']]
    for low, high in zip(points, points[1:]):
        if low['antisymmetric'] < 0 <= high['antisymmetric']:
            def mode(v):
                return core.pear_mode(v, c / radius, radius)[0]
            try:
                return brentq(mode, low['v'], high['v'], xtol=1e-6)
            except (ValueError, RuntimeError):
                return 0.5 * (low['v'] + high['v'])
    return None


def _pear_branch(c, v_pe, radius, others=(), amplitude=0.01, **limits):
    """Branch switching at the pear bifurcation v_pe: the prolate at v_pe - DV / 2 plus
    `amplitude` times its pear mode (`sharp.pear_mode`), minimized on all modes, followed
    down and up, unless that minimum is a point of one of the branches `others` (the same
    energy to 1e-8 at that v)."""
    branch = _Branch('pear', c, **limits)
    v = round(v_pe - DV / 2, 10)
    _, mode = core.pear_mode(v, c / radius, radius)
    _, x = core._embedded_prolate(v, c, 32)
    mu = None
    for sign in (1, -1):
        try:
            g = core._Grid(32, False)
            grid, x1, mu = _settle('pear', g, x + sign * amplitude * mode, v, c)
            x = x1
            break
        except (RuntimeError, np.linalg.LinAlgError) as error:
            branch.start = f'no start: {error}'
    if mu is None:
        return branch
    branch.start = (f'switched off the prolate at v {v:.4f} (pear bifurcation at {v_pe:.5f}) '
                    f'along its pear mode ({amplitude:g} of it)')
    E = float(core._evaluate(grid, x, c)[0][0])
    for other in others:
        vs = [p['v'] for p in other.points if other.kind != 'prolate']
        if vs and min(vs) - DV < v < max(vs) + DV:
            try:
                same = abs(_energy_at(other, v) / E - 1) < 1e-8
            except (RuntimeError, np.linalg.LinAlgError):
                same = False
            if same:
                branch.start += (f': the minimum found there (E {E:.6f}, asymmetry '
                                 f'{_asymmetry(grid, x):.2f}) is the {other.kind} branch\'s '
                                 f'point at that v, not a small-amplitude pear; no branch of '
                                 f'its own')
                return branch
    _follow(branch, grid, x, mu, v, -1)
    _follow(branch, grid, x, mu, v, +1, record_first=False)
    return branch


def _neck_branch(kind, c, v_start, **limits):
    """A narrow-neck branch from two spheres at v_start: unequal on all modes ('neck pear'),
    equal on the even modes ('neck dumbbell'); followed down and up."""
    branch = _Branch(kind, c, **limits)
    grid = core._Grid(START_N[kind], kind == 'neck dumbbell')
    x = _two_spheres(grid, v_start)
    try:
        grid, x, mu = _settle(kind, grid, x, v_start, c)
    except (RuntimeError, np.linalg.LinAlgError) as error:
        branch.start = f'no start: {error}'
        return branch
    branch.start = f'two spheres joined by a smoothed neck, minimized at v {v_start:g}'
    _follow(branch, grid, x, mu, v_start, -1)
    _follow(branch, grid, x, mu, v_start, +1, record_first=False)
    return branch


# --- the diagram of one row -----------------------------------------------------------------

def _energy_at(branch, v):
    """E of `branch` at v, by minimization from its nearest point."""
    points, states = branch.sorted()
    i = int(np.argmin([abs(p['v'] - v) for p in points]))
    grid, x = states[i]
    grid, x, _ = _settle(branch.kind, grid, x, v, branch.c)
    return float(core._evaluate(grid, x, branch.c)[0][0])


def stored_energy(row, name, v, asymmetric=False, floor=1e-6):
    """E of branch `name` of a stored row (an entry of `rows` in the JSON a diagram is
    kept in) at v, linear between its points; NaN outside them, or without the branch.
    With `asymmetric`, only its points of up-down asymmetry above `floor` count (the neck
    pear, which turns into the symmetric neck dumbbell as v falls)."""
    b = row['branches'].get(name)
    if not b or not b['v']:
        return math.nan
    order = np.argsort(b['v'])
    vs, es = np.asarray(b['v'])[order], np.asarray(b['E'])[order]
    if asymmetric:
        keep = np.asarray(b['asymmetry'])[order] > floor
        vs, es = vs[keep], es[keep]
    if len(vs) < 2 or not vs[0] - 1e-9 <= v <= vs[-1] + 1e-9:
        return math.nan
    return float(np.interp(v, vs, es))


def _on_grid(branch):
    """{grid index: energy} of the branch's points on the v grid."""
    return {round(_grid_index(p['v'])): p['E'] for p in branch.points if p['on_grid']}


def _label(branch, k):
    """The region name of branch's point at grid index k (the neck pear that has become
    symmetric is a neck dumbbell)."""
    if branch.kind == 'neck pear':
        p = next(p for p in branch.points if p['on_grid'] and round(_grid_index(p['v'])) == k)
        return 'neck pear' if p['asymmetry'] > ASYMMETRIC else 'neck dumbbell'
    return branch.kind


def _diagram_row(branches):
    """Least energy per grid v, its regions and its transitions."""
    energies = {b.kind: _on_grid(b) for b in branches}
    ks = sorted(set().union(*energies.values()))
    least = {}
    for k in ks:
        # two branches within 1e-9 of each other are one state (the neck pear that has become
        # symmetric is the neck dumbbell): the first listed names it
        here = [(e[k], kind) for kind, e in energies.items() if k in e]
        lowest = min(E for E, _ in here)
        least[k] = next(kind for E, kind in here if E <= lowest + 1e-9 * abs(lowest))
    regions, transitions = [], []
    by_kind = {b.kind: b for b in branches}
    for k in ks:
        name = _label(by_kind[least[k]], k)
        v = round(V_MAX - k * DV, 10)
        if regions and regions[-1]['branch'] == name and regions[-1]['k'] == k - 1:
            regions[-1].update(low=v, k=k)
        else:
            regions.append(dict(branch=name, high=v, low=v, k=k))
    for k in ks:
        if k + 1 not in least or least[k + 1] == least[k]:
            continue
        a, b = least[k], least[k + 1]            # a at the higher v, b at the lower
        hi, lo = round(V_MAX - k * DV, 10), round(V_MAX - (k + 1) * DV, 10)
        A, B = by_kind[a], by_kind[b]
        if k + 1 in energies[a] and k in energies[b]:
            def difference(v):
                return _energy_at(A, v) - _energy_at(B, v)
            try:
                v = brentq(difference, lo, hi, xtol=1e-10)
                transitions.append(dict(v=v, above=a, below=b, E=_energy_at(A, v),
                                        E_below=_energy_at(B, v), kind='crossing'))
                continue
            except (ValueError, RuntimeError) as error:
                note = f'no root ({error})'
        else:
            note = 'a branch ends between the grid points'
        ends = [e['v'] for e in A.ends if e['direction'] < 0 and lo < e['v'] < hi] + \
               [e['v'] for e in B.ends if e['direction'] > 0 and lo < e['v'] < hi]
        v = float(np.mean(ends)) if ends else 0.5 * (hi + lo)
        where = ' and '.join(f'{e:.4f}' for e in ends) or f'{lo:.4f}-{hi:.4f}'
        transitions.append(dict(v=v, above=a, below=b, E=math.nan, E_below=math.nan,
                                kind=f'at the branch ends {where} ({note})'))
    # the neck pear turning into the neck dumbbell along one branch
    if 'neck pear' in by_kind:
        pts = [p for p in by_kind['neck pear'].sorted()[0] if p['on_grid']]
        for p, q in zip(pts, pts[1:]):
            if (p['asymmetry'] > ASYMMETRIC) != (q['asymmetry'] > ASYMMETRIC):
                transitions.append(dict(v=0.5 * (p['v'] + q['v']), above='neck pear',
                                        below='neck dumbbell', E=0.5 * (p['E'] + q['E']),
                                        E_below=math.nan,
                                        kind='the neck pear becomes symmetric (grid spacing)'))
    transitions.sort(key=lambda t: -t['v'])
    for r in regions:
        del r['k']
    return regions, transitions


def _describe_end(branch, end):
    """One sentence: where and why a branch ended."""
    if end['reason'] == 'the range':
        return f"{'down' if end['direction'] < 0 else 'up'}: reached the range at v {end['v']:.4f}"
    points = branch.points
    last = min(points, key=lambda p: abs(p['v'] - end['v']))
    near = sorted(points, key=lambda p: abs(p['v'] - end['v']))[:12]
    lam = last['eigenvalue']
    typical = max(abs(p['eigenvalue']) for p in near)
    extra = []
    if typical > 0 and abs(lam) < 0.15 * typical:
        extra.append(f'least eigenvalue {lam:.2g} against {typical:.2g} nearby: a fold')
    if not math.isnan(last['neck']) and branch.kind != 'oblate':
        extra.append(f"neck {last['neck']:.4f} R")
    if branch.kind == 'oblate':
        extra.append(f"gap between the dimples {last['gap']:.4f} R")
    if branch.kind in ('pear', 'neck pear'):
        extra.append(f"asymmetry {last['asymmetry']:.2g}")
    extra.append(f"n {last['n']}")
    return (f"{'down' if end['direction'] < 0 else 'up'}: ends at v {end['v']:.4f} "
            f"(next tried {end.get('tried', math.nan):.4f}: {end['reason']}); "
            + ', '.join(extra))


def _folds(branch):
    """Folds: ends whose last point has a vanishing least eigenvalue, located by a linear
    fit of lambda^2 against v over the last three points (lambda ~ sqrt(v - v_fold))."""
    found = []
    for end in branch.ends:
        if end['reason'] == 'the range':
            continue
        pts = sorted(branch.points, key=lambda p: abs(p['v'] - end['v']))[:3]
        near = sorted(branch.points, key=lambda p: abs(p['v'] - end['v']))[:12]
        typical = max(abs(p['eigenvalue']) for p in near)
        if typical <= 0 or abs(pts[0]['eigenvalue']) > 0.15 * typical or len(pts) < 3:
            continue
        vs = np.array([p['v'] for p in pts])
        lam2 = np.array([p['eigenvalue'] ** 2 for p in pts])
        slope, intercept = np.polyfit(vs, lam2, 1)
        v_fold = -intercept / slope if slope != 0 else end['v']
        found.append(dict(v=float(v_fold), last=end['v'], direction=end['direction']))
    return found


def row(c0, radius=1.0, kinds=None, neck=None, v_min=V_MIN, v_max=V_MAX):
    """Every branch at the reduced spontaneous curvature c0 = 2 C0 R of a scene of radius R =
    `radius` (C0 R0 = c0 / 2 in the solver's unit; `sharp.solve(v, branch, c0=c0 / (2 R),
    radius=R)` has the same energies), followed over the v grid; the least energy, its regions
    and transitions. `kinds` limits the branches (default all; the neck branches at c0 in
    NECK_ROWS or if `neck`), v_min and v_max the range followed (the prolate and the oblate
    start at V_MAX whatever v_max).

    Returns plain data (lists, dicts, floats, strings):
    dict(c0, regions=[dict(branch, high, low)], transitions=[dict(v, above, below, E,
    E_below, kind)], branches={kind: dict(start, ends, folds, v, E, tension, pressure, n,
    neck, gap, asymmetry, eigenvalue, antisymmetric, on_grid)}, wall) with the regions and the
    transitions from high v to low, each branch's points in increasing v, energies in units
    of k, tension and pressure the solver's multipliers (unit R0 and k), wall in seconds."""
    limits = dict(v_min=v_min, v_max=v_max)
    start = time.perf_counter()
    c = c0 / 2
    kinds = kinds or ['prolate', 'oblate', 'stomatocyte'] + (
        ['neck pear', 'neck dumbbell'] if (neck if neck is not None else c0 in NECK_ROWS)
        else []) + ['pear']
    branches = []
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        for kind in kinds:
            if kind in ('prolate', 'oblate'):
                branches.append(_standard_branch(kind, c, **limits))
            elif kind == 'stomatocyte':
                branches.append(_stomatocyte_branch(c, **limits))
            elif kind == 'pear':
                prolate = next((b for b in branches if b.kind == 'prolate'), None)
                v_pe = _pear_point(prolate, c, radius) if prolate and prolate.points else None
                if v_pe is None:
                    b = _Branch('pear', c)
                    b.start = ('no pear bifurcation of the prolate in the range (the '
                               'antisymmetric eigenvalue keeps its sign)')
                    branches.append(b)
                else:
                    branches.append(_pear_branch(c, v_pe, radius, branches, **limits))
            elif kind == 'neck pear':
                branches.append(_neck_branch(kind, c, 0.74, **limits))
            elif kind == 'neck dumbbell':
                branches.append(_neck_branch(kind, c, 0.70, **limits))
        followed = [b for b in branches if b.points]
        regions, transitions = _diagram_row(followed) if followed else ([], [])
    result = dict(c0=c0, regions=regions, transitions=transitions, branches={})
    for b in branches:
        points = b.sorted()[0]
        result['branches'][b.kind] = dict(
            start=b.start, ends=[_describe_end(b, e) for e in b.ends], folds=_folds(b),
            **{key: [p[key] for p in points] for key in
               ('v', 'E', 'tension', 'pressure', 'n', 'neck', 'gap', 'asymmetry',
                'eigenvalue', 'antisymmetric', 'on_grid')})
    result['wall'] = time.perf_counter() - start
    return result

