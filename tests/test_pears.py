"""The pears study's (runs/pears/pears.py) extrapolation of the pitchfork in eps (no PETSc)."""
import math

import pytest

from scripts import load

pears = load('runs/pears/pears.py')


def row(eps, d, adapted=0):
    return dict(eps=eps, bifurcation=d, adapted=adapted)


def test_the_eps_squared_fit_recovers_its_limit_from_uniform_rows_only():
    d0, c = 3.85, -700.0
    rows = [row(e, d0 + c * e * e) for e in (0.04, 0.03, 0.02)]
    rows += [row(0.01, 4.7, adapted=0.02), row(0.015, math.nan)]
    fit = pears.extrapolate(rows)
    assert fit[0] == pytest.approx(d0, abs=1e-12) and fit[1] == pytest.approx(c, rel=1e-10)
    assert fit[2] < 1e-12
    noisy = pears.extrapolate(rows[:3] + [row(0.015, d0 + c * 0.015 ** 2 + 0.01)])
    assert 1e-3 < noisy[2] < 0.01 and abs(noisy[0] - d0) < 0.02


def test_one_bifurcation_gives_no_fit():
    assert pears.extrapolate([row(0.04, 2.7), row(0.03, math.nan)]) is None
