"""Accuracy on demand (`pf.accurate`, `-pf_tol`): the error bar's rule, the budget, the
topology check, a resumed sequence, and the command line on the coarse discocyte."""
import math
import sys
import time

import h5py
import pytest

import pfmembrane as pf
from pfmembrane import accuracy
from pfmembrane.io import options
from pfmembrane.io.options import UsageError
from pfmembrane.parallel import faults

SHARP = 9.1265694  # the sharp discocyte, v 0.8, R 0.4 (runs/sharp/validation.md)
TOL = 1e-2
# eps0 0.06 in the auto box: phi_h = 0 is a torus there (the dimple pinched at the axis),
# so the sequence meets an under-resolved step first, then two estimates.
EPS0 = 0.06


def step(eps, estimate, usable=True):
    return accuracy.Step(eps, 1000, 0.8 * eps, estimate, usable, True, 1.0, 0.0, '')


def test_the_bar_needs_two_estimates_and_covers_linear_convergence():
    assert math.isnan(accuracy.error_bar([step(0.04, 9.2)])[1])
    assert math.isnan(accuracy.error_bar([step(0.04, 9.2), step(0.03, math.nan, False)])[1])
    # error C eps: at ratio 1/2 the difference is the error, at 1/sqrt2 the bar is 2.41 times it
    for ratio in (0.5, 2 ** -0.5):
        steps = [step(0.04, SHARP + 0.04), step(0.04 * ratio, SHARP + 0.04 * ratio)]
        estimate, bar = accuracy.error_bar(steps)
        assert estimate == SHARP + 0.04 * ratio
        assert bar == pytest.approx(abs(estimate - SHARP), rel=1e-9)
    # faster convergence: the bar covers with room; an unusable step in between is skipped
    steps = [step(0.04, SHARP + 0.04 ** 2), step(0.03, math.nan, False),
             step(0.02, SHARP + 0.02 ** 2)]
    estimate, bar = accuracy.error_bar(steps)
    assert bar == pytest.approx(3 * 0.02 ** 2) and bar > abs(estimate - SHARP)
    assert accuracy.reached(steps, 2e-4) and not accuracy.reached(steps, 1e-4)


def test_a_uniform_step_resolves_its_eps():
    box = pf.Scene(box='auto').sized(0.04).box
    n = accuracy.uniform_nodes(box, 0.04)
    assert 1500 < n < 1900  # (0.78 x 0.98) / (sqrt3/2 (0.04/1.75)^2)


def test_the_options_are_checked():
    def read(*args):
        return options.read(options.Table.from_files(args=list(args)))
    assert read('-pf_tol', '1e-3').tol == 1e-3 and read().tol == 0.0
    for args, message in ((['-pf_tol', '1.5'], '-pf_tol must be in'),
                          (['-pf_tol', '1e-3', '-pf_tol_nodes', '10'], '-pf_tol_nodes must be'),
                          (['-pf_tol', '1e-3', '-pf_tol_time', '0'], '-pf_tol_time must be'),
                          (['-pf_tol', '1e-3', '-pf_restart', 'x.h5'], 'resumes from its steps'),
                          (['-pf_tol', '1e-3', '-pf_modes', '2'], '-pf_modes with -pf_tol')):
        with pytest.raises(UsageError, match=message):
            read(*args)


@pytest.fixture(scope='module')
def comm():
    return pf.api.petsc(sys.argv[:1]).COMM_SELF


def test_a_first_grid_over_the_node_budget_is_refused_before_any_solve(comm, monkeypatch):
    monkeypatch.setattr(accuracy, 'solve', None)  # any solve would fail
    with pytest.raises(UsageError, match=r'-pf_tol_nodes 500: the first step'):
        pf.accurate(pf.Scene(box='auto'), TOL, eps0=0.04, max_nodes=500, comm=comm)


@pytest.fixture(scope='module')
def sequence(comm, tmp_path_factory):
    """The coarse discocyte to TOL 1e-2 in two calls on one checkpoint directory: the
    first with its second step cut by the time budget (its deadline already past), the
    second resuming. Each call's solves counted."""
    directory = str(tmp_path_factory.mktemp('tol') / 'steps')
    calls = []
    solve = accuracy.solve

    def counted(*args, **kwargs):
        calls[-1].append(kwargs.get('eps', args[2] if len(args) > 2 else None))
        if len(calls) == 1 and len(calls[0]) == 2:
            with faults.deadline(-math.inf):
                return solve(*args, **kwargs)
        return solve(*args, **kwargs)

    runs = []
    accuracy.solve = counted
    try:
        for _ in range(2):
            calls.append([])
            lines = []
            res = pf.accurate(pf.Scene(box='auto'), TOL, eps0=EPS0, checkpoints=directory,
                              adapt=True, comm=comm, print_fn=lines.append)
            runs.append((res, lines))
    finally:
        accuracy.solve = solve
    return runs, calls, directory


@pytest.mark.slow
def test_a_step_cut_by_the_time_budget_stops_with_tol_not_reached(sequence):
    res, lines = sequence[0][0]
    a = res.attrs
    assert a['tol_reached'] == 0
    assert a['tol_stop'].startswith('time budget: the step at eps 0.04243')
    assert any('TOL not reached (time budget' in line for line in lines)
    assert len(a['tol_eps']) == 1 and a['tol_eps'][0] == EPS0  # the cut step is no step
    assert res.status == 0 and res.attrs['tol_step'] == 0


def test_a_deadline_stops_the_poll_on_time():
    mpi = pf.api.petsc(sys.argv[:1]).COMM_SELF.tompi4py()
    faults.poll(mpi)  # no deadline
    with faults.deadline(time.perf_counter() + 60):
        faults.poll(mpi)
        with faults.deadline(-math.inf):
            with pytest.raises(faults.OutOfTime):
                faults.poll(mpi)
        with faults.deadline(math.inf):  # a later deadline leaves the earlier in force
            faults.poll(mpi)
    faults.poll(mpi)


@pytest.mark.slow
def test_a_node_budget_below_the_next_grid_stops_with_tol_not_reached(comm):
    lines = []
    res = pf.accurate(pf.Scene(box='auto'), TOL, eps0=0.0425, max_nodes=2000, adapt=False,
                      comm=comm, print_fn=lines.append)
    a = res.attrs
    assert a['tol_reached'] == 0 and a['tol_stop'].startswith('node budget')
    assert list(a['tol_nodes']) == [res.grid.n_nodes] and res.grid.n_nodes <= 2000
    assert a['sharp_estimate'] == res.level_set_energy and math.isnan(a['sharp_error'])
    assert 'TOL not reached (node budget' in lines[-2]


@pytest.mark.slow
def test_an_under_resolved_topology_is_no_estimate(sequence):
    first, lines = sequence[0][0]
    assert first.topology == '1 torus' and first.attrs['tol_usable'] == 0
    assert any(line.startswith(f'under-resolved: topology 1 torus at eps {EPS0:g}')
               for line in lines)
    assert math.isnan(first.attrs['sharp_estimate'])


@pytest.mark.slow
def test_a_rerun_resumes_from_the_last_step_found(sequence):
    runs, calls, directory = sequence
    assert calls[0] == [EPS0, calls[1][0]]
    assert calls[1] and EPS0 not in calls[1]  # step 0 is read back, not solved again
    # the step the budget cut was not kept: it is solved again
    assert any('resuming after step 0' in line for line in runs[1][1])
    with h5py.File(f'{directory}/step1.h5') as f:
        assert f.attrs['tol_step'] == 1 and f.attrs['tol_usable'] == 1


@pytest.mark.slow
def test_the_coarse_discocyte_converges_within_tol_with_a_bar_that_covers(sequence):
    res, lines = sequence[0][1]
    a = res.attrs
    assert a['tol_reached'] == 1 and any('TOL reached' in line for line in lines)
    estimate, bar = a['sharp_estimate'], a['sharp_error']
    assert estimate == res.level_set_energy
    assert abs(estimate - SHARP) <= TOL * SHARP
    assert abs(estimate - SHARP) <= bar <= TOL * abs(estimate)
    assert len(a['tol_eps']) == len(a['tol_nodes']) >= 3 and a['tol_eps'][0] == EPS0
    assert any(line.startswith('tol step') and 'CVT f=' in line for line in lines)
    assert all(e >= 0 for e in a['tol_nodes']) and a['tol_wall_time'] > 0


@pytest.mark.slow
def test_the_command_line_writes_the_estimate(pfm, tmp_path):
    out = tmp_path / 'disc.h5'
    done = pfm('-options_file', 'options/discocyte.opts', '-pf_box', 'auto', '-pf_eps', '0.0425',
               '-pf_tol', str(TOL), '-pf_output', out, n=1)
    assert done.returncode == 0, done.stderr[-2000:]
    assert 'TOL reached' in done.stdout
    with h5py.File(out) as f:
        a = dict(f.attrs)
    assert a['tol_reached'] == 1 and abs(a['sharp_estimate'] - SHARP) <= a['sharp_error']
    assert a['sharp_error'] <= TOL * a['sharp_estimate']
    assert (tmp_path / 'disc_tol' / 'step0.h5').exists()
    assert (tmp_path / 'disc_tol' / 'step1.h5').exists()


@pytest.mark.slow  # a sharp stomatocyte: about 2 s alone
def test_the_first_eps_follows_the_sharp_start_s_smallest_feature(monkeypatch):
    monkeypatch.setattr(accuracy, 'solve', None)  # no solve
    # the stomatocyte at v 0.6: its sharp neck 2 r = 0.0991 puts eps0 at a quarter of it,
    # 0.0248 (pinched there, then an eighth: `next_eps`)
    stomatocyte = pf.Scene(branch='stomatocyte', reduced_volume=0.6, box='auto')
    eps0, feature = accuracy.first_eps(stomatocyte, 0.04)
    assert feature.kind == 'neck' and feature.size == pytest.approx(0.0991, abs=5e-4)
    assert eps0 == pytest.approx(accuracy.FIRST_FRACTION * feature.size)
    assert 0.024 < eps0 < 0.026
    assert accuracy.first_eps(stomatocyte, 0.01)[0] == 0.01  # a smaller eps0 stays
    assert accuracy.first_eps(stomatocyte)[0] == eps0        # R / 10 = 0.04 by default
    # the spheroids have no sharp start: eps0 as given
    assert accuracy.first_eps(pf.Scene(box='auto'), 0.06) == (0.06, None)
    assert accuracy.first_eps(pf.Scene(branch='prolate', box='auto'))[0] == pytest.approx(0.04)


def test_an_under_resolved_step_jumps_to_the_feature():
    sharp = accuracy.first_eps(pf.Scene(branch='stomatocyte', reduced_volume=0.6,
                                        box='auto'))[1]
    pinched = accuracy.Step(0.04, 1000, 0.03, math.nan, False, True, 1.0, 0.0,
                            'under-resolved: topology 2 spheres at eps 0.04')
    eps, reference = accuracy.next_eps([pinched], 2 ** -0.5, 0.04, sharp)
    assert eps == pytest.approx(accuracy.FRACTION * sharp.size) and 'neck' in reference[1]
    # the last usable level set's feature comes first; one ratio step where that is smaller
    usable = accuracy.Step(0.03, 1000, 0.025, 12.5, True, True, 1.0, 0.0, '', 0.08, 'gap')
    assert accuracy.next_eps([usable, pinched], 0.5, 0.04, sharp) == \
        (pytest.approx(0.01), (0.08, 'gap'))
    assert accuracy.next_eps([usable, pinched], 0.2, 0.04, sharp)[0] == pytest.approx(0.008)
    # a feature within 2.5 eps of its step is held at the interface: the sharp start's instead
    held = accuracy.Step(0.03, 1000, 0.025, 12.5, True, True, 1.0, 0.0, '', 0.06, 'gap')
    assert accuracy.next_eps([held, pinched], 0.5, 0.04, sharp)[1][0] == sharp.size
    # after a usable step, or without any feature known: one ratio step
    assert accuracy.next_eps([usable], 0.5, 0.04, sharp)[0] == pytest.approx(0.015)
    assert accuracy.next_eps([pinched], 0.5, 0.04, None) == (pytest.approx(0.02), None)
    assert accuracy.next_eps([], 0.5, 0.04, sharp) == (0.04, None)


def test_a_graded_grid_only_where_the_uniform_one_exceeds_the_node_budget(monkeypatch):
    asked = []

    def graded(scene, eps, start=None, max_nodes=None, params=None, comm=None):
        asked.append(max_nodes)
        return 'grid', start, 'graded about the sharp start', 0.9 * eps

    monkeypatch.setattr(accuracy, 'graded_grid', graded)
    monkeypatch.setattr(accuracy.Grid, 'uniform', classmethod(lambda *a, **k: 'uniform'))
    monkeypatch.setattr(accuracy, '_lattice_resolves', lambda grid: 0.03)
    scene = pf.Scene(box='auto')
    count = accuracy.uniform_nodes(scene.sized(0.04).box, 0.04)
    plan = accuracy._plan(scene, 0.04, None, None, 'auto', 2.0, {}, count, None)
    assert plan[1] == 'uniform' and plan[4] == 0.03 and asked == []  # within the budget
    plan = accuracy._plan(scene, 0.04, None, None, 'auto', 2.0, {}, count - 100, None)
    assert plan[1:] == ('grid', None, 'graded about the sharp start', 0.9 * 0.04)
    assert asked == [count - 100]
    assert accuracy._plan(scene, 0.04, None, None, False, 2.0, {}, count - 100, None) == \
        f"{count} nodes" and len(asked) == 1  # adapt=False: never graded


@pytest.mark.slow  # one solve of 11,000 nodes on one rank: about 40 s
def test_a_narrow_neck_gets_a_graded_grid_that_resolves_it(comm):
    # the stomatocyte at v 0.6 at eps 0.0085 on the grid graded about its sharp start
    stomatocyte = pf.Scene(branch='stomatocyte', reduced_volume=0.6, box='auto').sized(0.0085)
    grid, start, how, resolves = accuracy.graded_grid(stomatocyte, 0.0085, comm=comm)
    assert how.startswith('graded about the sharp start') and start is None
    assert grid.n_nodes < 0.8 * accuracy.uniform_nodes(stomatocyte.box, 0.0085)
    assert resolves == grid.eps_min <= 0.0085
    res = pf.solve(stomatocyte, grid, 0.0085, checks=True)
    assert res.converged and res.topology == '1 sphere'
    # the level set within 1e-4 of the sharp 12.424253 (runs/accuracy/graded.md: +0.0015% at
    # eps 0.00876 on both kinds of grid)
    assert res.level_set_energy == pytest.approx(12.424253, rel=1e-4)


def test_a_feature_closing_as_eps_falls_is_a_limit_shape():
    def usable(eps, feature, kind='neck'):
        return accuracy.Step(eps, 1000, 0.9 * eps, 1.0, True, True, 1.0, 0.0, '', feature, kind)
    # the narrow-neck dumbbell at c0 2.5, v 0.7 (runs/accuracy/narrow.md): slope 0.59
    dumbbell = [usable(e, f) for e, f in ((0.04, 0.221), (0.0283, 0.166), (0.02, 0.128),
                                          (0.0141, 0.101), (0.01, 0.0851))]
    slope, kind, eps = accuracy.closing(dumbbell)
    assert kind == 'neck' and eps == [0.02, 0.0141, 0.01]
    assert slope == pytest.approx(math.log(0.128 / 0.0851) / math.log(2.0), rel=2e-2)
    # an open neck (the stomatocyte at v 0.6), too few estimates, two kinds: none
    assert accuracy.closing([usable(0.0248, 0.0991), usable(0.0124, 0.0973),
                             usable(0.00876, 0.0954)]) is None
    assert accuracy.closing(dumbbell[-2:]) is None
    assert accuracy.closing(dumbbell[:-1] + [usable(0.01, 0.0851, 'gap')]) is None
    # an unusable step in between is skipped
    pinched = accuracy.Step(0.012, 1000, 0.01, math.nan, False, True, 1.0, 0.0,
                            'under-resolved: topology 2 spheres at eps 0.012')
    assert accuracy.closing(dumbbell[:-1] + [pinched, dumbbell[-1]])[2] == [0.02, 0.0141, 0.01]
    assert accuracy.following(dumbbell) is None


def test_a_feature_that_follows_eps_is_under_resolution():
    def usable(eps, feature):
        return accuracy.Step(eps, 1000, 0.9 * eps, 1.0, True, True, 1.0, 0.0, '', feature, 'gap')
    # the oblate at c0 1, v 0.55 (sharp gap 0.063): its gap near 2 eps (slope 1.07)
    oblate = [usable(e, f) for e, f in ((0.01414, 0.0283), (0.01, 0.0188), (0.00707, 0.0129),
                                        (0.005, 0.00895))]
    slope, kind, eps = accuracy.following(oblate)
    assert kind == 'gap' and eps == [0.01, 0.00707, 0.005] and 1.0 < slope < 1.1
    assert accuracy.closing(oblate) == (slope, kind, eps)
    # the oblate at c0 -1, v 0.55 (sharp gap 0.0275): still closing at 3.3 eps, no verdict
    closing = [usable(e, f) for e, f in ((0.04, 0.126), (0.0283, 0.101), (0.02, 0.0664))]
    assert accuracy.closing(closing)[0] > 0.9 and accuracy.following(closing) is None
