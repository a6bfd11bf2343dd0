"""Nodes graded about a curve (`kernels.grading`): the spacing law, the node count it
implies, and the CVT that places them."""
import numpy as np
import pytest
from scipy.integrate import quad

from pfmembrane.kernels import grading
from pfmembrane.kernels.nodes import nodal_spacing

BOX = (0.4, 0.6)
LINE = np.array([[0.2, 0.0], [0.2, 0.6]])   # a vertical line across the box
H0, WIDTH, GRADE, H_MAX = 0.005, 0.01, 0.3, 0.03


def test_the_spacing_is_flat_in_the_band_and_grows_linearly_to_its_ceiling():
    d = np.array([0.0, WIDTH, WIDTH + 0.01, WIDTH + 1.0])
    h = grading.spacing(d, H0, WIDTH, GRADE, H_MAX)
    assert h[0] == h[1] == H0
    assert h[2] == pytest.approx(H0 + GRADE * 0.01) and h[3] == H_MAX


def test_the_distance_counts_the_mirror_image_across_the_axis():
    near_axis = np.array([[0.01, 0.3]])
    d = grading.curve_distance(near_axis, [np.array([[0.02, 0.0], [0.02, 0.6]])], 1e-3)
    assert d[0] == pytest.approx(0.01, abs=1e-3)
    # an arc around the axis: its mirror image is nearer than the arc itself
    d = grading.curve_distance(np.array([[0.0, 0.3]]), [np.array([[0.05, 0.0], [0.05, 0.6]])],
                               1e-3)
    assert d[0] == pytest.approx(0.05, abs=1e-3)


def test_the_count_is_the_integral_of_the_hexagonal_density():
    # a line across the box: d = |r - 0.2| (its mirror at r = -0.2 is farther), so
    # N = Zb * 2 * int_0^0.2 dd / (HEX h(d)^2)
    integral = quad(lambda d: 1.0 / (grading.HEX * grading.spacing(d, H0, WIDTH, GRADE,
                                                                      H_MAX) ** 2),
                    0.0, 0.2, points=[WIDTH, WIDTH + (H_MAX - H0) / GRADE])[0]
    count = grading.node_count(*grading.spacing_raster([LINE], BOX, H0, WIDTH, GRADE, H_MAX))
    assert count == pytest.approx(2 * BOX[1] * integral, rel=0.02)


@pytest.fixture(scope='module')
def graded():
    return grading.graded_nodes(*grading.spacing_raster([LINE], BOX, H0, WIDTH, GRADE, H_MAX),
                                BOX)


def test_the_cvt_places_the_count_with_the_band_s_spacing(graded):
    nodes, steps, movement = graded
    count = grading.node_count(*grading.spacing_raster([LINE], BOX, H0, WIDTH, GRADE, H_MAX))
    assert len(nodes) == pytest.approx(count, rel=0.01) and 0 < steps and movement < 1e-3
    assert (nodes >= 0).all() and (nodes <= BOX).all()
    h = nodal_spacing(nodes)
    d = np.abs(nodes[:, 0] - 0.2)
    # spacing h0 in the band (the mean neighbour distance of a hexagonal lattice is h)
    assert np.median(h[d < 0.5 * WIDTH]) == pytest.approx(H0, rel=0.15)
    # and as the law says where it grows (the CVT smooths the corner a little)
    far = (d > 0.06) & (d < 0.07) & (nodes[:, 1] > 0.1) & (nodes[:, 1] < 0.5)
    expected = grading.spacing(0.065, H0, WIDTH, GRADE, H_MAX)
    assert np.median(h[far]) == pytest.approx(expected, rel=0.25)


def test_a_mirror_plane_grades_the_half_box():
    half_raster = grading.spacing_raster([LINE], BOX, H0, WIDTH, GRADE, H_MAX, plane=0.3)
    nodes, _, _ = grading.graded_nodes(*half_raster, BOX, plane=0.3)
    full = grading.node_count(*grading.spacing_raster([LINE], BOX, H0, WIDTH, GRADE, H_MAX))
    assert (nodes[:, 1] >= 0.3 - 1e-12).all()
    # half of the full count, and the half box's own count; the start lattice's row on the
    # plane adds about one row's nodes (797 against 750 here)
    half = grading.node_count(*half_raster)
    assert half == pytest.approx(0.5 * full, rel=0.01)
    assert half < len(nodes) < 1.08 * half
