"""The genus-one study (runs/harmonics/torus.py): its limit in the highest harmonic J,
Aitken's delta-squared on the level-set energies at the last three J, and its grids."""
import numpy as np
import pytest

from scripts import load

torus = load('runs/harmonics/torus.py')


def test_a_geometric_truncation_error_extrapolates_to_its_limit():
    # E_J = E + c q^(J/2): the limit and q come back exactly; the axisymmetric entry
    # (J = 0) and the tori lost on the way (NaN) take no part
    energies = {0: 11.0, 6: np.nan, **{J: 9.87 + 0.4 * 0.35 ** (J / 2) for J in (8, 10, 12)}}
    limit, q = torus.extrapolated(energies)
    assert limit == pytest.approx(9.87, rel=1e-12) and q == pytest.approx(0.35, rel=1e-12)


@pytest.mark.parametrize('energies', [
    {8: 10.0, 10: 9.9, 14: 9.85},    # J not equally spaced
    {8: 10.0, 10: 9.9, 12: 9.95},    # the differences change sign (q < 0)
    {8: 10.0, 10: 9.9, 12: 9.75},    # they grow (q > 1)
    {10: 9.9, 12: 9.85},             # two J only
])
def test_no_limit_without_three_geometrically_converging_j(energies):
    assert np.isnan(torus.extrapolated(energies)[0])


def test_a_scaled_grid_keeps_the_papers_ratio_of_eps_to_the_spacing():
    # the paper's 6,124 nodes of 1.5 x 2 at eps 0.04; halving eps quadruples the nodes
    assert torus.nodes((1.5, 2.0)) == 6124
    assert torus.nodes((1.5, 2.0), 0.02) == 4 * 6124
    assert torus.nodes((0.8, 1.0), 0.05) == round(6124 * 0.8 / 3.0 * 0.64)
