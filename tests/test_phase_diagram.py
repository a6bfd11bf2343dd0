"""The phase-field diagram's verdicts (runs/phase_diagram/diagram.py) on made-up rows: which
sharp branch a state is, where two states cross, what a grid point's least state says."""
import math

import pytest

from scripts import load

diagram = load('runs/phase_diagram/diagram.py')
V = [round(0.55 + 0.005 * i, 3) for i in range(81)]


def row(crossing=0.7):
    """Two lines crossing at v = crossing: the prolate 10 - 2 (v - crossing), the oblate
    10 + 3 (v - crossing); the oblate least below it."""
    branch = lambda e: {'v': V, 'E': [e(v) for v in V], 'asymmetry': [0.0] * len(V)}  # noqa: E731
    return diagram.Sharp({
        'c0': 0.0,
        'regions': [{'branch': 'prolate', 'high': 0.95, 'low': 0.7},
                    {'branch': 'oblate', 'high': 0.695, 'low': 0.55}],
        'transitions': [{'v': crossing, 'above': 'prolate', 'below': 'oblate', 'E': 10.0,
                         'kind': 'crossing'}],
        'branches': {'prolate': branch(lambda v: 10 - 2 * (v - crossing)),
                     'oblate': branch(lambda v: 10 + 3 * (v - crossing)),
                     'stomatocyte': {'v': [], 'E': []}}})


def point(sharp, v, family, error=0.0, bar=1e-3, status='reached'):
    p = {'c0': 0.0, 'v': v, 'family': family, 'tol': 1e-3, 'status': status, 'wall': 1.0,
         'estimate': sharp.energy(family, v) * (1 + error), 'bar': bar, 'eps': [0.02],
         'nodes': [1000], 'features': [0.3], 'feature_kind': 'neck', 'closing': math.nan,
         'follows': math.nan, 'stop': '', 'topology': '1 sphere'}
    p['state'], p['sharp'], p['relative'] = diagram.name_state(p, sharp)
    return p


def test_a_state_is_the_sharp_branch_nearest_in_energy():
    sharp = row()
    assert point(sharp, 0.8, 'prolate', 0.001)['state'] == 'prolate'
    far = point(sharp, 0.8, 'prolate', 0.47, bar=0.01)
    assert far['state'] == 'unmatched' and far['relative'] == pytest.approx(0.47)
    # three bars cover a larger difference
    assert point(sharp, 0.8, 'prolate', 0.01, bar=0.05)['state'] == 'prolate'


def test_the_crossing_is_the_zero_of_the_difference():
    sharp = row(0.7013)
    points = [point(sharp, v, f) for v in (0.6913, 0.7113) for f in ('prolate', 'oblate')]
    rows, found = diagram.crossing_rows(sharp, points)
    assert found[0][1] == pytest.approx(0.7013, abs=1e-12)
    assert rows[0][5] == 'agrees'
    # the states' errors move it by their difference (+0.02) over the slope 5
    points = [point(sharp, v, f, 0.002 if f == 'oblate' else 0.0)
              for v in (0.6913, 0.7113) for f in ('prolate', 'oblate')]
    rows, found = diagram.crossing_rows(sharp, points)
    assert found[0][1] == pytest.approx(0.7013 - 0.02 / 5, rel=1e-3)
    assert rows[0][5] == 'agrees'
    # TOL not reached: its bar still locates the crossing; without a bar, or held at the
    # interface width, the state is not used
    points[-1]['status'] = 'not reached'
    assert diagram.crossing_rows(sharp, points)[1] == found
    for change in ({'bar': math.nan}, {'follows': 1.07}):
        rows, located = diagram.crossing_rows(sharp, points[:-1] + [dict(points[-1], **change)])
        assert not located and rows[0][5].startswith('not located: oblate at v 0.7113')


def test_the_bracket_tol_keeps_the_crossing_within_half_the_window():
    sharp = row()
    # slope 5, E 10: 0.5 x 0.005 x 5 / 10 = 1.25e-3, capped at 1e-3
    assert diagram.bracket_tol(sharp, sharp.transitions[0]) == diagram.BRACKET_TOL
    flat = dict(sharp.transitions[0], E=1000.0)
    assert diagram.bracket_tol(sharp, flat) == diagram.TOL_FLOOR
    assert diagram.bracket_tol(sharp, dict(flat, E=50.0)) == pytest.approx(2.5e-4)


def test_the_least_state_at_a_grid_point():
    sharp = row()
    least = lambda points: diagram.least_rows(sharp, points)[GRID_075][3]  # noqa: E731
    agree = [point(sharp, 0.75, 'prolate'), point(sharp, 0.75, 'oblate')]
    assert least(agree) == 'agrees'
    # the oblate 0.35 below the prolate, beyond their bars: least where the sharp prolate is
    swapped = [point(sharp, 0.75, 'prolate', 0.04, bar=0.15),
               point(sharp, 0.75, 'oblate', -0.02, bar=0.1)]
    assert least(swapped).startswith('DISAGREES: oblate below the prolate')
    close = [point(sharp, 0.75, 'prolate', 0.0255, bar=0.2),
             point(sharp, 0.75, 'oblate', 0.0, bar=0.2)]
    assert close[0]['state'] == 'prolate'
    assert least(close).startswith('undecided at this TOL')
    unresolved = [dict(agree[0], status='not reached', bar=math.nan, stop='time budget'),
                  agree[1]]
    assert least(unresolved).startswith('not resolved: the prolate (not reached')


GRID_075 = diagram.GRID.index(0.75)
