"""`levelset.smallest_feature` on analytic meridian curves: a circle, a dumbbell with a known
neck, two concentric arcs (a gap), a torus (a hole), and a stomatocyte-like curve given as
`level_set` would give it."""
import numpy as np
import pytest

from pfmembrane.analysis.levelset import smallest_feature


def arc(radius, start, stop, n=400, centre=(0.0, 0.0)):
    t = np.linspace(start, stop, n)
    return np.column_stack([centre[0] + radius * np.sin(t), centre[1] - radius * np.cos(t)])


def test_a_circle_has_no_neck_and_no_gap_its_diameter():
    f = smallest_feature(arc(0.4, 0.0, np.pi))
    assert f.kind == 'diameter' and f.size == pytest.approx(0.8, rel=1e-4)
    # an (r, z) pair is the same curve
    r, z = arc(0.4, 0.0, np.pi).T
    assert smallest_feature((r, z)).size == pytest.approx(0.8, rel=1e-4)


def test_a_dumbbell_has_its_neck():
    # two lobes (r up to ~rl at z = +-1/2) joined by a smooth neck of radius rn at z = 0
    z = np.linspace(-1.0, 1.0, 2001)
    rn, rl = 0.08, 0.3
    r = np.sqrt(1.0 - z ** 2) * (rn + (rl - rn) * np.sin(np.pi * z) ** 2)
    f = smallest_feature((r, z))
    assert f.kind == 'neck'
    assert f.size == pytest.approx(2 * rn, rel=2e-3)
    assert f.where[1] == pytest.approx(0.0, abs=2e-3)


def test_two_concentric_arcs_are_a_gap_of_the_difference_of_radii():
    # an outer and an inner membrane, joined at the top by a semicircular lip (one piece,
    # axis to axis, as a stomatocyte's meridian) and as two separate pieces
    outer, inner = 0.4, 0.33
    top = np.pi - np.arcsin(0.1 / outer)
    lip_r = 0.5 * (outer - inner)
    a = arc(outer, 0.0, top)
    centre = 0.5 * (a[-1] + arc(inner, top, top, 1)[0])
    angle = np.arctan2(*(a[-1] - centre)[::-1])
    lip = np.column_stack([centre[0] + lip_r * np.cos(angle + np.linspace(0, np.pi, 60)),
                           centre[1] + lip_r * np.sin(angle + np.linspace(0, np.pi, 60))])
    b = arc(inner, top, 0.0)
    f = smallest_feature([np.vstack([a, lip[1:-1], b])])
    assert f.kind == 'gap' and f.size == pytest.approx(outer - inner, rel=5e-3)
    f = smallest_feature([a, b])
    assert f.kind == 'gap' and f.size == pytest.approx(outer - inner, rel=5e-3)


def test_a_torus_has_its_hole():
    loop = arc(0.2, 0.0, 2 * np.pi, centre=(0.25, 0.5))  # hole 2 (0.25 - 0.2) = 0.1
    f = smallest_feature([loop])
    assert f.kind == 'hole' and f.size == pytest.approx(0.1, rel=1e-3)
    assert f.where[0] == pytest.approx(0.05, rel=1e-3)
    # a fat hole: the tube is the smaller
    f = smallest_feature([arc(0.1, 0.0, 2 * np.pi, centre=(0.5, 0.0))])
    assert f.kind == 'tube' and f.size == pytest.approx(0.2, rel=1e-3)


def test_neighbours_along_a_wavy_curve_are_no_gap():
    # a sphere with small ripples: no neck deeper than the ripples' rise, no gap
    t = np.linspace(0.0, np.pi, 3000)
    rho = 0.4 * (1 + 0.002 * np.sin(40 * t))
    f = smallest_feature((rho * np.sin(t), -rho * np.cos(t)))
    assert f.kind == 'diameter' and f.size == pytest.approx(0.8, rel=1e-2)
