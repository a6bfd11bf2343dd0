"""Accuracy on demand: the sharp-limit energy of a scene to a relative
tolerance, by solves at decreasing eps on grids that resolve each eps, with an
error bar (`accurate`; the command line's `-pf_tol`).

The estimate is the level set's own energy (`Result.level_set_energy`: the
Canham-Helfrich energy of phi_h = 0 put on the scene's area and volume, from
`solve(..., checks=True)`), which approaches the sharp energy far faster than
the phase-field energy (runs/limit/notes.md). The driver does by itself what
the adaptive sequences of options/adapt/ do by hand:

- **steps**: eps_k = eps0 ratio^k (eps0 by default R / 10, ratio 1/sqrt 2); each
  step starts from the previous usable step's phi_h (its tanh profile rescaled
  to the new eps), or from the scene's start after an unusable one;
- **resolution follows the shape**: where the family starts from its sharp shape
  (the stomatocyte), eps0 is at most FIRST_FRACTION times that curve's smallest
  feature (`levelset.smallest_feature`: a neck, the gap between two membranes,
  a torus's hole; `first_eps`), and after every usable step the feature of its
  phi_h = 0 is measured (`tol_feature`). After an under-resolved step the next
  eps is FRACTION times the feature of the last usable level set (else of the
  sharp start) where that is below one ratio step;
- **resolution**: every grid has `Grid.eps_min <= eps` (on uniform grids also
  1.5 times the median spacing, `_lattice_resolves`): the previous grid when
  it resolves eps, else a uniform grid of the box sized for eps (`Scene.sized`;
  a fixed box stays) with spacing h = eps / 1.75 on the hexagonal lattice, about
  Rb Zb / (sqrt3/2 h^2) nodes of the full box. Where that grid would exceed
  `max_nodes` and the membrane is known (the previous usable step's phi_h = 0,
  else the sharp start), a grid graded about it (`graded_grid`: that spacing
  within 8 eps of the membrane, growing by 0.3 per unit distance beyond),
  whose count grows like 1 / eps where the uniform one's grows like 1 / eps^2.
  Only there: on the stomatocyte at v 0.6 both kinds give the same level set
  (12.424979 and 12.424971 at eps 0.0124, 12.424446 and 12.424427 at 0.00876,
  runs/accuracy/graded.md), but at c0 -0.5 the graded grid's E at eps 0.0063
  was 1.1% above the uniform one's and its solves at 0.00446 (from the step
  before) and 0.00315 did not converge where the uniform grid's at 0.00446
  did (runs/accuracy/narrow_stomatocyte_m0.5.md). Where the graded grid
  would exceed
  `max_nodes` (`adapt='auto'`, the default), or first (`adapt=True`), the
  previous result's nodes relocated by CVT (`grid.adapt`'s density
  1 + f |grad phi_h| with a `band` of 2 eps: f 10, then 100, then 2, 4, ...
  times the nodes with f 100; max-ent locality gamma at most 0.4 on them,
  `ADAPT_GAMMA`), kept only when the relocation's eps_min (checked before the
  basis is built) is <= eps. Uniform comes first by default because, measured
  on 2 ranks, the graded grids cost more time and memory than the uniform
  grids of the auto box they replace (the stomatocyte at eps 0.01: 7,313
  adapted nodes 31.5 s, 12,782 uniform ones 20.8 s; gamma 0.4 widens the
  supports): adaptivity saves nodes, not time;
- **topology**: phi_h = 0 must be what the family is (one sphere; one torus for
  the `torus` branch; `expect`). A step whose level set is another (a
  stomatocyte's neck pinched, say) is under-resolved: it is no estimate, the
  driver says "under-resolved: topology X at eps Y (smallest feature: neck
  0.0991)" and goes on at the next eps (above) from the scene's start. A
  feature that keeps closing as eps falls (over the last three estimates, at
  least like eps^0.5: `closing`) is no under-resolution but a limit shape, a
  sharp limit with a feature of zero width: the driver says "a LIMIT SHAPE"
  (attributes `tol_closing`, the slope, and `tol_closing_kind`); one that
  closes like eps^0.9 or faster and ends within 2.5 eps follows the interface,
  an under-resolution ("UNDER-RESOLVED: the gap follows eps"; `tol_follows`,
  `tol_follows_kind`). A solve that
  does not converge is no estimate either; after two in a row the driver stops;
- **error bar**: from the last two estimates E_a, E_b at eps_a > eps_b (never
  from one), r = eps_b / eps_a: bar = max(1, r / (1 - r)) |E_b - E_a|. If the
  error of the estimate is e(eps) = C eps^p with p >= 1, then E_a - E_b =
  C eps_a^p (1 - r^p) and e(eps_b) = |E_a - E_b| r^p / (1 - r^p) <=
  |E_a - E_b| r / (1 - r): the bar covers the error of E_b whenever the error
  falls at least linearly and monotonically in eps. Measured: in the paper's
  box the discocyte's level set is +0.0226% at eps 0.04, +0.0010% at 0.01; in
  the auto box (its bulk offset adds an eps^3 term) +0.287%, +0.066%, +0.016%,
  +0.0039% at eps 0.04, 0.028, 0.02, 0.014, where the bar was 8, 7.6 and 7.4
  times the true error (the dumbbell 5.6, the stomatocyte at v 0.6 4.2). With
  ratio 1/sqrt 2 the factor is 2.41, with 1/2 it is 1. The grids
  scale with eps (eps / h_min held by the resolution rule), so their
  discretization error is part of e(eps). What it cannot defend: two estimates
  that agree by chance where the error is not yet monotone (on uniform grids
  at eps 0.05 ... 0.03 the discocyte's level set is +0.0026%, +0.023%,
  +0.019%), which a smaller ratio or a smaller eps0 makes less likely;
- **stop**: when bar <= tol |E_b| (tol_reached 1), or at the budget: a grid of
  more than `max_nodes` nodes needed, or `max_time` seconds of this call spent
  (or predicted to be, from the last step's time scaled as nodes^1.5), or two
  failed solves in a row: then the best estimate is reported with
  tol_reached 0 and "TOL not reached (why)". A solve still running at
  `max_time` stops at its next iteration (`parallel.faults.deadline`), so the
  budget holds within one iteration; a solve stopped so, or by a signal, is no
  step and is not checkpointed (a signal's status goes to the result). Only a
  first step cut so returns an unconverged result without an estimate.
- **restart**: with `checkpoints` (a directory) every step's result is written
  there as step<k>.h5, its attributes `tol_step`, `tol_usable`, `tol_note` and
  the running `sharp_estimate`, `sharp_error`, `tol_reached`; a later call
  with the same directory reads the steps found (a scene that differs is
  refused) and goes on after the last, solving nothing when they already meet
  tol. The time budget counts this call only.
"""
import math
import os
import time
from dataclasses import dataclass, replace

import numpy as np

from pfmembrane.grid import RESOLUTION, Grid
from pfmembrane.io import checkpoint
from pfmembrane.io.options import Params, UsageError
from pfmembrane.parallel import faults, petsc
from pfmembrane.result import Result, read

# The uniform grid of a step: h = eps / H_RATIO on the hexagonal lattice (the paper's Table 1:
# eps 0.04 on spacing 0.024), so that eps_min = 1.5 h_min is about 0.86 eps.
H_RATIO = 1.75
HEX = math.sqrt(3.0) / 2.0
RATIO = 2.0 ** -0.5
FIRST_EPS = 0.1          # eps0 in units of R (the paper's 0.04 at R = 0.4)
MAX_NODES = 200000
MAX_TIME = 1800.0
ADAPT_F = (10.0, 100.0)  # CVT amplifications tried on the previous nodes, then twice as many
BAND = 2.0               # the CVT band in units of the step's eps (runs/atlas/notes.md: W = 2 eps)
# The largest max-ent locality on adapted grids: the paper's sequences take 0.5 and 0.4, the
# adapted stomatocyte 0.4; with 0.8 its eps 0.01 step on a graded grid came out 0.86% high in E
# with nu_V -2.03 against the sharp -3.71 (0.4: +0.088%, -3.76; uniform grid: +0.057%).
ADAPT_GAMMA = 0.4
# eps0 <= FIRST_FRACTION x the smallest feature of the sharp start, and after an under-resolved
# step eps <= FRACTION x that of the last usable level set (else of the sharp start). Measured on
# 2 ranks: the stomatocyte at v 0.6 (R 0.4) has a sharp neck of width 2 r = 0.0991 (its
# membranes' gap 0.138); its phi_h = 0 was one sphere at eps 0.0141 and 0.01 (0.142 and 0.101 of
# the neck) and pinched ("2 spheres", "1 torus") at 0.02, 0.028, 0.04 (0.20 of the neck and
# more). 1/8 puts eps at 0.0124, 12% under the largest eps that resolved, 38% under the one that
# pinched. At c0 -0.5 (neck 0.0252) phi_h = 0 stayed one sphere at eps 0.0063 (1/4 of it), and
# a solve at 1/8 from the sharp start did not converge (on a graded grid of 35,894 nodes:
# runs/accuracy/graded.md) where the steps 0.0063, 0.00446 from one another did (estimate
# +0.0226%: runs/accuracy/narrow_stomatocyte_m0.5_uniform.md). So the first step tries 1/4, cheaper by 4 to 16
# in nodes; where it pinches (c0 0: one step of about 2,400 nodes more) 1/8 follows.
FIRST_FRACTION = 0.25
FRACTION = 0.125
# Graded grids. The band of spacing eps / H_RATIO reaches GRADED_WIDTH eps from the membrane,
# where the profile's 1 + phi = 2 exp(-sqrt2 d / eps) is down to 2e-5; beyond, the spacing
# grows by GRADING per unit distance (`graded_grid`). With them, the stomatocyte at v 0.6 has the
# uniform grid's level set (runs/accuracy/graded.md); a band of 4 eps, where 1 + phi is still
# 7e-3, left its phase-field E 1.2% high at eps 0.00876 (not on a page: measured while choosing).
GRADED_WIDTH = 8.0
GRADING = 0.3
# A limit shape: the smallest feature of the last CLOSING_STEPS usable steps falls at least like
# eps^CLOSING_SLOPE. Measured on 2 ranks (runs/accuracy/narrow.md): the narrow-neck dumbbell at
# c0 2.5, v 0.7 (the sharp shape's neck closed) has necks 0.128, 0.101, 0.0851 at eps 0.02,
# 0.0141, 0.01 (slope 0.59), the stomatocyte at v 0.6 (an open neck of 0.099) 0.0973, 0.0954 at
# eps 0.0124, 0.00876 (0.06).
# A feature closing like eps^FOLLOWS_SLOPE or faster and within FOLLOWS_WIDTH eps follows the
# interface: it is set by eps, not by the shape, an under-resolution. Measured on 2 ranks: the
# oblate at c0 1, v 0.55 (the sharp gap 0.063) keeps its gap near 2 eps (0.0188, 0.0129,
# 0.00895 at eps 0.01, 0.00707, 0.005: slope 1.07) where the dumbbell's neck closes like
# eps^0.59; the oblate at c0 -1, v 0.55 (the sharp gap 0.0275) has gaps 0.126, 0.101, 0.0664
# at eps 0.04, 0.0283, 0.02 (slope 0.92, 3.3 eps): still closing towards the sharp gap.
CLOSING_STEPS = 3
CLOSING_SLOPE = 0.5
FOLLOWS_SLOPE = 0.9
FOLLOWS_WIDTH = 2.5
MAX_FAILED = 2           # unconverged solves in a row that end the sequence
EXPECTED = {'torus': '1 torus'}  # phi_h = 0 of each family; the others '1 sphere'
SCENE_KEYS = ('reduced_volume', 'c0', 'radius', 'k', 'branch', 'symmetric')


@dataclass
class Step:
    """One step of the sequence as the driver keeps it."""
    eps: float
    nodes: int
    eps_min: float
    estimate: float  # NaN when the step is no estimate
    usable: bool
    converged: bool
    wall: float
    adapt: float
    note: str
    feature: float = math.nan  # the smallest feature of its phi_h = 0 (NaN: not measured)
    feature_kind: str = ''


def uniform_nodes(box, eps):
    """The node count of the full box's hexagonal lattice of spacing eps / H_RATIO."""
    h = eps / H_RATIO
    return int(math.ceil(box[0] * box[1] / (HEX * h * h)))


def sharp_feature(scene):
    """The smallest feature (`levelset.Feature`) of the scene's sharp start, where its
    family starts from one (the stomatocyte: `starts.sharp_shape`), else None (the
    spheroids and the torus: no narrow feature to resolve first). Not collective."""
    from pfmembrane.analysis.levelset import smallest_feature
    shape = _sharp_shape(scene)
    if shape is None:
        return None
    return smallest_feature((np.asarray(shape.r), np.asarray(shape.z)))


def first_eps(scene, eps0=None, fraction=FIRST_FRACTION):
    """(eps0, feature): the first step's eps, min(eps0, fraction x the smallest feature
    of the scene's sharp start), eps0 by default R / 10, and that feature (None where
    the family has no sharp start: eps0 as given). Not collective; no solve."""
    eps0 = float(eps0) if eps0 is not None else FIRST_EPS * scene.radius
    feature = sharp_feature(scene)
    if feature is not None and math.isfinite(feature.size) and feature.size > 0:
        eps0 = min(eps0, fraction * feature.size)
    return eps0, feature


def next_eps(steps, ratio, eps0, sharp=None, fraction=FRACTION):
    """(eps, feature): the next step's eps after `steps`: eps0 first, then one ratio
    step, or after an under-resolved step (a topology other than the family's)
    fraction x the feature of the last usable level set (else of the `sharp` start)
    where that is smaller; and that feature as (size, kind), None if unknown."""
    if not steps:
        return eps0, None
    eps = steps[-1].eps * ratio
    feature = _reference_feature(steps, sharp)
    if steps[-1].note.startswith('under-resolved') and feature is not None:
        eps = min(eps, fraction * feature[0])
    return eps, feature


def _reference_feature(steps, sharp):
    """(size, kind) of the last usable step's level-set feature, else of the sharp start.
    A feature within FOLLOWS_WIDTH eps of its step is held at the interface, no measure of
    the shape, and is passed over: a fraction of it would jump to an eps far finer than the
    shape needs."""
    for s in reversed(steps):
        if s.usable and math.isfinite(s.feature) and s.feature > FOLLOWS_WIDTH * s.eps:
            return s.feature, s.feature_kind or 'feature'
    if sharp is not None:
        return sharp.size, f"{sharp.kind} of the sharp start"
    return None


def error_bar(steps):
    """(estimate, bar): the last usable step's estimate and the bar from it and the
    usable step before (module docstring); (NaN, NaN) without an estimate, bar NaN
    with one."""
    usable = [s for s in steps if s.usable]
    if not usable:
        return math.nan, math.nan
    if len(usable) == 1:
        return usable[-1].estimate, math.nan
    a, b = usable[-2], usable[-1]
    r = b.eps / a.eps
    factor = max(1.0, r / (1.0 - r)) if r < 1.0 else math.inf
    return b.estimate, factor * abs(b.estimate - a.estimate)


def closing(steps, count=CLOSING_STEPS, slope=CLOSING_SLOPE):
    """(p, kind, eps) where the smallest feature of the last `count` usable steps has one
    kind and falls with eps at least like eps^slope (p the least-squares slope of log
    feature against log eps, eps theirs): a feature still closing as eps falls, whose
    sharp limit is a feature of zero width (a limit shape); else None."""
    usable = [s for s in steps if s.usable and math.isfinite(s.feature) and s.feature > 0]
    last = usable[-count:]
    if len(last) < count or len({s.feature_kind for s in last}) != 1:
        return None
    eps = [s.eps for s in last]
    p = float(np.polyfit(np.log(eps), np.log([s.feature for s in last]), 1)[0])
    return (p, last[-1].feature_kind, eps) if p >= slope else None


def following(steps):
    """`closing(steps)` where the feature closes like eps^FOLLOWS_SLOPE or faster and ends
    within FOLLOWS_WIDTH eps: held at the interface width, an under-resolution, not a limit
    shape; else None."""
    limit = closing(steps)
    last = [s for s in steps if s.usable and math.isfinite(s.feature)]
    if limit and limit[0] >= FOLLOWS_SLOPE and last[-1].feature <= FOLLOWS_WIDTH * last[-1].eps:
        return limit
    return None


def reached(steps, tol):
    estimate, bar = error_bar(steps)
    return bool(math.isfinite(bar) and bar <= tol * abs(estimate))


def accurate(scene, tol, eps0=None, ratio=RATIO, max_nodes=MAX_NODES, max_time=MAX_TIME,
             checkpoints=None, adapt='auto', band=BAND, grid_options=None, options=None,
             expect=None, comm=None, print_fn=None):
    """The sharp-limit energy of `scene` to the relative tolerance `tol`: solves
    at eps0, eps0 ratio, eps0 ratio^2, ... on grids that resolve each eps, until
    the level set's own energy is within tol by its error bar or the budget is
    spent (the module docstring says how the steps, grids, bar, topology check,
    restart and budget work). Collective.

    `scene.box` may be 'auto' (sized for each eps). `eps0` defaults to R / 10,
    and is lowered to FIRST_FRACTION x the smallest feature of the sharp start where
    the family has one (`first_eps`);
    `max_nodes` bounds every grid, `max_time` (s) this call; `checkpoints` a
    directory for the steps' results (step<k>.h5), which a later call resumes
    from; `adapt` 'auto' adapts where a uniform grid would exceed max_nodes,
    True before any new uniform grid, False never; `band` the CVT band in units
    of eps; `grid_options` the `Grid` keywords (gamma, cutoff, ...),
    `options` the solves' (as `solve`'s); `expect` the topology phi_h = 0 must
    have ('1 sphere', or '1 torus' for the torus branch); `print_fn` a line per
    step and the verdict (None: silent).

    Returns the `Result` of the last usable step (of the last step when none
    is), its attrs holding `sharp_estimate` (the estimate), `sharp_error` (the
    bar, absolute, energy units; NaN with fewer than two estimates),
    `tol_reached` (1/0), `tol`, `tol_stop` (why it stopped), per step
    `tol_eps`, `tol_nodes`, `tol_estimates` (NaN: no estimate), `tol_features`
    (the smallest feature of each step's phi_h = 0; NaN: unusable), `tol_closing`
    and `tol_closing_kind` (`closing`: NaN and '' unless a limit shape),
    `tol_follows` and `tol_follows_kind` (the same for a feature that follows eps),
    `tol_wall_time` (this call, s) and `tol_steps_time` (the steps' walls,
    earlier calls' included); the same in the checkpoint it saves to. Every
    step's result and checkpoint holds `tol_feature` and `tol_feature_kind`.
    """
    t0 = time.perf_counter()
    if not (math.isfinite(tol) and 0.0 < tol < 1.0):
        raise UsageError(f"-pf_tol must lie in (0, 1) (got {tol!r})")
    if not 0.0 < ratio < 1.0:
        raise ValueError(f"ratio must lie in (0, 1) (got {ratio!r})")
    if adapt not in (True, False, 'auto'):
        raise ValueError(f"adapt must be True, False or 'auto' (got {adapt!r})")
    comm = petsc.comm(comm)
    mpi = comm.tompi4py()
    say = print_fn or (lambda *_: None)
    expect = expect or EXPECTED.get(scene.branch, '1 sphere')
    given = float(eps0) if eps0 is not None else FIRST_EPS * scene.radius
    eps0, sharp = first_eps(scene, given)
    params = dict(grid_options or {})
    options = dict(options or {})

    steps, results, prev = [], [], None
    if checkpoints:
        if mpi.Get_rank() == 0:
            os.makedirs(checkpoints, exist_ok=True)
        mpi.Barrier()
        steps, prev = _resume(checkpoints, scene, mpi, say)
    say(f"tol: {scene.branch} v={scene.reduced_volume:g} c0={scene.c0:g} R={scene.radius:g}: "
        f"TOL {tol:g}, eps from {next_eps(steps, ratio, eps0, sharp)[0]:.4g}"
        + (f" ({FIRST_FRACTION:g} x the sharp start's {sharp.kind} {sharp.size:.3g}, under "
           f"{given:g})" if not steps and eps0 < given else '')
        + f" by {ratio:.4g}, budget {max_nodes} nodes, {max_time:g} s"
        + (f", steps in {checkpoints}" if checkpoints else ''))
    unused, stop, halted = None, '', None
    while True:
        if reached(steps, tol):
            stop = 'TOL reached'
            break
        failed = 0
        for s in reversed(steps):
            if s.converged:
                break
            failed += 1
        if failed >= MAX_FAILED:
            stop = f"{failed} solves in a row did not converge"
            break
        k = len(steps)
        eps, reference = next_eps(steps, ratio, eps0, sharp)
        elapsed = mpi.allreduce(time.perf_counter() - t0, op=_max())
        if steps and elapsed + steps[-1].wall > max_time:
            stop = (f"time budget: {elapsed:.0f} s of {max_time:g} s spent, the last step "
                    f"took {steps[-1].wall:.0f} s")
            break
        t_step = time.perf_counter()
        plan = _plan(scene, eps, prev if prev is not None and steps[-1].usable else None,
                     steps[-1] if steps else None, adapt, band, params, max_nodes, comm)
        if isinstance(plan, str):
            if not steps:
                raise UsageError(f"-pf_tol_nodes {max_nodes}: the first step (eps {eps:g}) "
                                 f"needs {plan}")
            stop = (f"node budget: no grid of at most {max_nodes} nodes resolves eps {eps:.4g} "
                    f"(a uniform one: {plan})")
            break
        step_scene, grid, start, how, resolves = plan
        if steps:
            last = steps[-1]
            predicted = last.wall * (grid.n_nodes / max(last.nodes, 1)) ** 1.5
            elapsed = mpi.allreduce(time.perf_counter() - t0, op=_max())
            if elapsed + predicted > max_time:
                stop = (f"time budget: the next step (eps {eps:.4g}, {grid.n_nodes} nodes) "
                        f"would end near {elapsed + predicted:.0f} s > {max_time:g} s")
                break
        with faults.deadline(t0 + max_time):
            res = solve(step_scene, grid, eps, start=start, options=options, checks=True)
        if res.status > 1:  # the budget or a signal stopped the solve: no step to keep
            halted = res
            cut = mpi.allreduce(time.perf_counter() - t_step, op=_max())
            stop = ((f"time budget: the step at eps {eps:.4g} ({grid.n_nodes} nodes) stopped "
                     f"at {max_time:g} s, after {cut:.0f} s")
                    if res.status == faults.OutOfTime.status else
                    f"{res.message} during the step at eps {eps:.4g}")
            break
        unused = set(res.unused_options) if unused is None else unused & set(res.unused_options)
        topology = res.topology
        estimate = res.level_set_energy
        note = ''
        if not res.converged:
            note = f"not converged: {res.message}"
        elif topology != expect:
            note = f"under-resolved: topology {topology or 'none'} at eps {eps:g}" + (
                f" (smallest feature: {reference[1]} {reference[0]:.3g})"
                if reference is not None else '')
        elif not math.isfinite(estimate):
            note = f"no level-set energy at eps {eps:g}"
        usable = not note
        feature = ((res.attrs['feature_size'], res.attrs['feature_kind'])
                   if usable and 'feature_size' in res.attrs else None)
        wall = mpi.allreduce(time.perf_counter() - t_step, op=_max())
        f = (grid.adapt_info['f'] if grid.adapt_info else
             steps[-1].adapt if how == 'previous grid' else 0.0)
        steps.append(Step(eps, grid.n_nodes, resolves, estimate if usable else math.nan,
                          usable, res.converged, wall, f, note,
                          *(feature if feature else (math.nan, ''))))
        value, bar = error_bar(steps)
        res.attrs.update(wall_time=wall, tol_step=k, tol_usable=int(usable), tol_note=note,
                         tol_adapt=f, tol_resolves=resolves,
                         tol_grid=how, sharp_estimate=value, sharp_error=bar,
                         tol_feature=steps[-1].feature, tol_feature_kind=steps[-1].feature_kind,
                         tol_reached=int(reached(steps, tol)))
        results.append(res)
        prev = res
        if checkpoints:
            res.save(_step_path(checkpoints, k))
        say(f"tol step {k}: eps {eps:.4g}, {how}, {grid.n_nodes} nodes (resolves eps >= "
            f"{resolves:.4g}): E {res.energy:.6f}, level set {estimate:.6f}, "
            f"{topology or 'no level set'}"
            + (f", smallest feature {feature[1]} {feature[0]:.3g}" if feature else '') + "; " + (
                f"estimate {value:.6f} +- {bar:.2e} ({bar / abs(value):.2e} relative)"
                if math.isfinite(bar) else
                (f"estimate {value:.6f} (no bar from one estimate)" if usable else note))
            + f"; {wall:.1f} s" + (f" -> {_step_path(checkpoints, k)}" if checkpoints else ''))
        if not usable and res.converged and topology != expect:
            say(f"{note} (expected {expect}): not an estimate; eps reduced")
        elif not usable:
            say(f"tol step {k}: {note}: not an estimate")
    final = _final(steps, results, prev, checkpoints, mpi) if steps else halted
    if halted is not None and halted.status != faults.OutOfTime.status:
        final.status, final.message = halted.status, halted.message  # a signal: the run ends
    value, bar = error_bar(steps)
    done = reached(steps, tol)
    wall = mpi.allreduce(time.perf_counter() - t0, op=_max())
    final.attrs.update(
        sharp_estimate=value, sharp_error=bar, tol_reached=int(done), tol=tol,
        tol_ratio=ratio, tol_stop=stop, tol_eps=np.array([s.eps for s in steps]),
        tol_nodes=np.array([s.nodes for s in steps]),
        tol_estimates=np.array([s.estimate for s in steps]),
        tol_features=np.array([s.feature for s in steps]),
        tol_wall_time=wall, tol_steps_time=float(sum(s.wall for s in steps)))
    limit = closing(steps)
    follows = following(steps) is not None
    final.attrs.update(tol_closing=limit[0] if limit and not follows else math.nan,
                       tol_closing_kind=limit[1] if limit and not follows else '',
                       tol_follows=limit[0] if follows else math.nan,
                       tol_follows_kind=limit[1] if follows else '')
    final.unused_options = sorted(unused or ())
    relative = bar / abs(value) if math.isfinite(bar) and value else math.nan
    say(f"tol: sharp-limit estimate {value:.6f} "
        + (f"+- {bar:.2e} ({relative:.2e} relative, TOL {tol:g})" if math.isfinite(bar) else
           f"without an error bar ({'one estimate' if math.isfinite(value) else 'none'}, "
           f"TOL {tol:g})")
        + ": " + ("TOL reached" if done else f"TOL not reached ({stop})"))
    if follows:
        slope, kind, eps = limit
        say(f"tol: UNDER-RESOLVED: the {kind} follows eps (like eps^{slope:.2f} over eps "
            f"{' '.join(format(e, '.4g') for e in eps)}): held at the interface width, not "
            "the shape's own; the estimate is no sharp limit")
    elif limit:
        slope, kind, eps = limit
        say(f"tol: a LIMIT SHAPE: the {kind} closes as eps falls (like eps^{slope:.2f} over eps "
            f"{' '.join(format(e, '.4g') for e in eps)}): its sharp limit is a {kind} of zero "
            "width, which no eps resolves; the estimate converges as slowly")
    say(f"tol: eps {' '.join(format(s.eps, '.4g') for s in steps)}; nodes "
        f"{' '.join(str(s.nodes) for s in steps)}; {wall:.1f} s "
        f"(steps {sum(s.wall for s in steps):.1f} s)")
    return final


def solve(scene, grid, eps, start=None, options=None, checks=False):
    """`equilibrium.solve` (a name of this module, for the tests to count the solves)."""
    from pfmembrane.equilibrium import solve as solve_
    return solve_(scene, grid, eps, start=start, options=options, checks=checks)


def _max():
    from mpi4py import MPI
    return MPI.MAX


def _step_path(directory, k):
    return os.path.join(directory, f"step{k}.h5")


def _plan(scene, eps, prev, last, adapt, band, params, max_nodes, comm):
    """(scene on the grid's box, grid, start, how, resolves) for a step at `eps` after
    the usable result `prev` (None: a fresh start), `resolves` the smallest eps the grid
    resolves; or a string (the node count needed) when every grid that resolves eps
    exceeds `max_nodes`."""
    half = 2 if scene.symmetric else 1
    sized = scene.sized(eps)
    count = uniform_nodes(sized.box, eps)
    over = count // half > max_nodes
    if prev is not None:
        on_box = replace(scene, box=tuple(float(b) for b in prev.attrs['box']))
        if last.eps_min <= eps:   # the previous grid resolves eps: the same basis
            grid = prev.grid if prev.grid is not None and prev.grid.fits(on_box) else \
                Grid.of(prev, comm=comm, **{k: v for k, v in params.items() if k == 'partition'})
            return on_box, grid, prev, 'previous grid', last.eps_min
    start = _moved(prev, sized) if prev is not None else None
    if over and adapt == 'auto':
        found = graded_grid(sized, eps, start, max_nodes=max_nodes, params=params, comm=comm)
        if found is not None:
            return (sized, *found)
    if prev is not None and (adapt is True or (adapt == 'auto' and over)):
        ceiling = max_nodes if adapt == 'auto' else min(max_nodes, count // half - 1)
        found = _adapted(on_box, prev, last.adapt, eps, band, ceiling, params, comm)
        if found is not None:
            return (on_box, *found, found[0].eps_min)
    if over:
        return f"{count // half} nodes"
    grid = Grid.uniform(sized, count, comm=comm, **params)
    if _lattice_resolves(grid) > eps:  # the lattice rounded coarse: once more, finer
        count = int(count * (_lattice_resolves(grid) / eps) ** 2 * 1.05) + 1
        if count // half > max_nodes:
            return f"{count // half} nodes"
        grid = Grid.uniform(sized, count, comm=comm, **params)
    return (sized, grid, start, f"uniform {sized.box[0]:g}x{sized.box[1]:g}",
            _lattice_resolves(grid))


def graded_grid(scene, eps, start=None, max_nodes=MAX_NODES, params=None, comm=None):
    """(grid, start, how, resolves): a grid of `scene` (its box sized) graded about the
    membrane (`kernels.grading`: spacing eps / H_RATIO within GRADED_WIDTH eps of it,
    growing by GRADING per unit distance up to R / 10); the membrane is phi_h = 0 of
    `start` (in the scene's box), else the scene's sharp start (`starts.sharp_shape`);
    None where there is neither, or the grid exceeds `max_nodes` or does not resolve
    eps. Collective."""
    from pfmembrane.analysis.levelset import membrane
    from pfmembrane.kernels import grading
    from pfmembrane.kernels.nodes import nodal_spacing, spacing_peak
    if start is not None:
        curves = membrane(start.unfolded())  # the level set is found on the full box
        of = f"step {start.attrs.get('tol_step', '?')}'s phi_h = 0"
    else:
        shape = _sharp_shape(scene)
        curves = [] if shape is None else [
            np.column_stack([shape.r, np.asarray(shape.z) + scene.zc])]
        of = 'the sharp start'
    if not curves:
        return None
    h0, h_max = eps / H_RATIO, FIRST_EPS * scene.radius
    for _ in range(2):
        raster = grading.spacing_raster(curves, scene.box, h0, GRADED_WIDTH * eps, GRADING,
                                        h_max, scene.plane)
        if grading.node_count(*raster) > max_nodes:
            return None
        nodes, _, _ = grading.graded_nodes(*raster, scene.box, scene.plane)
        # the grid's eps_min, before its basis is built
        resolves = RESOLUTION * spacing_peak(nodal_spacing(nodes, plane=scene.plane))
        if resolves <= eps:
            grid = Grid(scene, nodes, comm=comm, **(params or {}))
            if grid.eps_min <= eps:
                return grid, start, (f"graded about {of}: h {h0:.3g} within "
                                     f"{GRADED_WIDTH * eps:.3g}, grading {GRADING:g}"), \
                    grid.eps_min
            resolves = grid.eps_min
        h0 *= eps / resolves / 1.02  # the CVT came out coarse: once more, finer
    return None


def _sharp_shape(scene):
    """The scene's sharp start, where its family has one (`sharp_feature`), else None."""
    from pfmembrane.io.options import start_kind
    if start_kind(scene.branch) != 'sharp':
        return None
    from pfmembrane import starts
    try:
        return starts.sharp_shape(scene)
    except UsageError:
        return None


def _lattice_resolves(grid):
    """The smallest eps a uniform grid resolves: the larger of its `eps_min` and
    RESOLUTION times the median nodal spacing. On some lattices the column squeezed
    against r = Rb forms the left peak of the spacings that `eps_min` reads (the
    auto box 0.8 x 1.01 with 1,584 nodes: eps_min 0.0278, the lattice's 0.0374), a
    resolution the membrane, away from that edge, does not have."""
    return max(grid.eps_min, RESOLUTION * float(np.median(grid.discrete.h)))


def _moved(prev, scene):
    """`prev` as a start in `scene`'s box: its nodes shifted in z so that the vesicle
    stays at the middle height Zb / 2 of the new box (the moment constraint's)."""
    old = tuple(float(b) for b in prev.attrs['box'])
    if np.allclose(old, scene.box, rtol=0, atol=1e-12):
        return prev
    shift = 0.5 * (scene.box[1] - old[1])
    return Result(prev.nodes + np.array([0.0, shift]), prev.phi,
                  {**prev.attrs, 'box': np.asarray(scene.box)}, path=prev.path)


def _adapted(scene, prev, f_prev, eps, band, ceiling, params, comm):
    """(grid, start, how): the first CVT relocation that resolves `eps` (`ADAPT_F` above
    the previous grid's `f_prev` on prev's nodes, then 2, 4, ... times as many nodes with
    the largest f, at most `ceiling`), or None."""
    n = len(prev.nodes)
    tries = [(n, f) for f in ADAPT_F if f > f_prev and n <= ceiling]
    grown = 2 * n
    while grown <= ceiling:
        tries.append((grown, ADAPT_F[-1]))
        grown *= 2
    for count, f in tries:
        found = _relocated(scene, prev, eps, f, band * eps, count, params, comm)
        if found is not None:
            grid, start = found
            return grid, start, (f"CVT f={f:g} band={band * eps:.3g} "
                                 f"gamma={grid.params['gamma']:g} of step "
                                 f"{prev.attrs.get('tol_step', '?')}")
    return None


def _relocated(scene, prev, eps, f, band, count, params, comm):
    """(grid, start): the CVT relocation of `prev`'s nodes (of `count` uniform nodes
    with prev's phi_h when count exceeds prev's) for the density 1 + f |grad phi_h|,
    as `grid.adapt` makes it, or None when its eps_min exceeds `eps` (checked before
    the basis is built)."""
    from pfmembrane.kernels import nodes as nodesets
    from pfmembrane.kernels.adapt import transfer
    from pfmembrane.parallel.adapt import relocate
    plane, box = scene.plane, scene.box
    source = prev
    if count > len(prev.nodes):
        xy = nodesets.uniform(box, count * (2 if scene.symmetric else 1), half=scene.symmetric)
        phi = transfer(prev.nodes, prev.phi, prev.locality(plane), prev.basis['cutoff'],
                       xy, box, plane)
        source = Result(xy, phi, {**prev.attrs, 'n_nodes': len(xy)}, path=prev.path)
    xy, phi, info = relocate(comm.tompi4py(), source.nodes, source.phi, box,
                             source.locality(plane), source.basis['cutoff'], f, plane,
                             None, band)
    if RESOLUTION * info['h_min'][1] > eps:
        return None
    gamma = min(params.get('gamma', Params.gamma), ADAPT_GAMMA)
    grid = Grid(scene, xy, comm=comm, **{**params, 'gamma': gamma})
    if grid.eps_min > eps:
        return None
    info['of'] = prev.path or 'the previous step'
    grid.adapt_info, grid.transferred = info, (source, phi)
    return grid, source


def _resume(directory, scene, mpi, say):
    """The steps found in `directory` (step0.h5, step1.h5, ... up to the first missing
    or unreadable one) and the last one's result."""
    steps, last = [], None
    while os.path.exists(_step_path(directory, len(steps))):
        path = _step_path(directory, len(steps))
        try:
            res = read(path, mpi)
        except checkpoint.CheckpointError:
            say(f"tol: {path} unreadable: solved again")
            break
        a = res.attrs
        theirs = res.scene
        differs = [key for key in SCENE_KEYS if getattr(theirs, key) != getattr(scene, key)]
        if differs or int(a.get('tol_step', -1)) != len(steps):
            raise UsageError(
                f"{path} is not a step of this scene ({', '.join(differs) or 'tol_step'} "
                "differs): give another -pf_output or remove that directory")
        usable = bool(a.get('tol_usable', 0))
        steps.append(Step(float(a['eps']), len(res.nodes),
                          float(a.get('tol_resolves', a['eps_min'])),
                          float(a['level_set_energy']) if usable else math.nan, usable,
                          bool(a['converged']), float(a['wall_time']),
                          float(a.get('tol_adapt', 0.0)), str(a.get('tol_note', '')),
                          float(a.get('tol_feature', math.nan)),
                          str(a.get('tol_feature_kind', ''))))
        last = res
    if steps:
        say(f"tol: resuming after step {len(steps) - 1} found in {directory}")
    return steps, last


def _final(steps, results, prev, directory, mpi):
    """The result of the last usable step (of the last step when none is): in memory
    when this call solved it, else read back from its checkpoint."""
    usable = [k for k, s in enumerate(steps) if s.usable]
    k = usable[-1] if usable else len(steps) - 1
    first = len(steps) - len(results)  # the steps this call solved
    if k >= first:
        return results[k - first]
    if k == len(steps) - 1 and prev is not None:
        return prev
    return read(_step_path(directory, k), mpi)


def save(result, path, comm=None):
    """Write `result` collectively: with its grid's communicator, or `comm` for a
    result read back (no grid), rank 0 writing."""
    if result.grid is not None:
        return result.save(path)
    mpi = petsc.comm(comm).tompi4py()
    checkpoint.write(path, result.nodes, result.phi, result.attrs, comm=mpi,
                     datasets={k: v for k, v in result.datasets.items() if k != 'triangles'},
                     triangles=result.datasets.get('triangles'))
    result.path = str(path)
    return result


def steps_directory(output):
    """The directory of a command-line run's steps: `<output stem>_tol`."""
    return os.path.splitext(output)[0] + '_tol'


def execute(p, comm, print_fn, solve_options=None):
    """The command line's `-pf_tol` run of the options `p` (`io.options.Params`):
    `accurate` from -pf_eps, with the steps in `<output stem>_tol/`, and the final
    result written to -pf_output. Collective. Returns (result, checkpoint path)."""
    from pfmembrane.scene import Scene
    from pfmembrane.io import options as opts
    output = p.output or opts.default_output(p)
    scene = Scene(p.reduced_volume, p.c0, p.radius, p.k, p.box, p.branch, p.symmetric)
    grid_options = dict(gamma=p.gamma, cutoff=p.cutoff, quad_degree=p.quad_degree,
                        spacing_smoothing=p.spacing_smoothing, spacing_floor=p.spacing_floor,
                        partition=p.partition)
    res = accurate(scene, p.tol, eps0=p.eps, max_nodes=p.tol_nodes, max_time=p.tol_time,
                   checkpoints=steps_directory(output), grid_options=grid_options,
                   options={**(solve_options or {}), 'pf_summary': True}, comm=comm,
                   print_fn=print_fn)
    if not res.converged and not res.status:  # a step read back that did not converge
        res.status = 1
    stage = petsc.start().Log.Stage('pfCheckpoint')
    stage.push()
    try:
        save(res, output, comm)
    finally:
        stage.pop()
    return res, output
