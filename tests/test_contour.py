"""Tests of pfmembrane.analysis.contour against matplotlib's contour."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from pfmembrane.analysis.contour import zero_contour

TOL = 1e-12
# Axes not symmetric about 0 and of unequal spacing: no raster point or cell
# mean is exactly 0 in the smooth fields below.
X = np.linspace(-1.3, 1.1, 61)
Y = np.linspace(-1.2, 1.25, 53)


def matplotlib_contour(x, y, F):
    return [line for line in Figure().add_subplot().contour(x, y, F, levels=[0.0]).allsegs[0]
            if len(line) > 1]


def is_closed(line):
    return np.allclose(line[0], line[-1], rtol=0.0, atol=TOL)


def same_polyline(ours, theirs):
    """Equal point sequences to TOL, either way round, and for closed ones
    from any start."""
    if len(ours) != len(theirs) or is_closed(ours) != is_closed(theirs):
        return False
    if is_closed(ours):
        ours, theirs = ours[:-1], theirs[:-1]
        start = np.argmin(np.hypot(*(theirs - ours[0]).T))
        candidates = [np.roll(theirs, -start, axis=0),
                      np.roll(theirs[::-1], start + 1, axis=0)]
    else:
        candidates = [theirs, theirs[::-1]]
    return any(np.allclose(ours, c, rtol=0.0, atol=TOL) for c in candidates)


def assert_matches_matplotlib(x, y, F, count=None):
    ours, theirs = zero_contour(x, y, F), matplotlib_contour(x, y, F)
    assert len(ours) == len(theirs) == (len(theirs) if count is None else count)
    unmatched = list(range(len(theirs)))
    for line in ours:
        assert line.dtype == float and line.ndim == 2 and line.shape[1] == 2
        matches = [k for k in unmatched if same_polyline(line, theirs[k])]
        assert matches, f"no matplotlib polyline matches {line[:3]}..."
        unmatched.remove(matches[0])
    return ours


def field(f, x=X, y=Y):
    return f(*np.meshgrid(x, y))


def test_circle_is_one_closed_polyline():
    [line] = assert_matches_matplotlib(X, Y, field(lambda x, y: 0.8 - x ** 2 - y ** 2), 1)
    assert is_closed(line)
    assert np.allclose(np.hypot(*line.T), np.sqrt(0.8), atol=0.01)


def test_ellipse_crossing_the_boundary_is_open():
    lines = assert_matches_matplotlib(
        X, Y, field(lambda x, y: 1.0 - (x / 1.5) ** 2 - (y / 0.7) ** 2), 2)
    # The upper and lower arcs, each from the side x = X[0] to x = X[-1].
    for line in lines:
        assert np.allclose(np.sort(line[[0, -1], 0]), X[[0, -1]], rtol=0.0, atol=TOL)
    assert sorted(np.sign(np.mean(line[:, 1])) for line in lines) == [-1.0, 1.0]


def test_two_blobs_are_two_closed_polylines():
    F = field(lambda x, y: np.exp(-((x + 0.6) ** 2 + y ** 2) / 0.1)
              + np.exp(-((x - 0.5) ** 2 + (y - 0.3) ** 2) / 0.05) - 0.5)
    lines = assert_matches_matplotlib(X, Y, F, 2)
    assert all(is_closed(line) for line in lines)


def test_ring_is_two_closed_polylines():
    lines = assert_matches_matplotlib(
        X, Y, field(lambda x, y: 0.04 - (np.hypot(x, y) - 0.7) ** 2), 2)
    assert all(is_closed(line) for line in lines)
    radii = sorted(np.mean(np.hypot(*line.T)) for line in lines)
    assert np.allclose(radii, [0.5, 0.9], atol=0.01)


SADDLE_X, SADDLE_Y = np.linspace(-2.05, 2.1, 90), np.linspace(-2.1, 2.02, 85)


@pytest.mark.parametrize("F, count", [
    (field(lambda x, y: np.sin(3 * x) * np.sin(3 * y), SADDLE_X, SADDLE_Y), 10),
    pytest.param(np.random.default_rng(0).standard_normal((85, 90)), None,
                 marks=pytest.mark.slow),
])
def test_saddles_are_resolved_as_by_matplotlib(F, count):
    inside = F > 0.0
    saddles = ((inside[:-1, :-1] == inside[1:, 1:]) & (inside[:-1, 1:] == inside[1:, :-1])
               & (inside[:-1, :-1] != inside[:-1, 1:]))
    mean = (F[:-1, :-1] + F[:-1, 1:] + F[1:, :-1] + F[1:, 1:])[saddles]
    assert np.any(mean > 0.0) and np.any(mean < 0.0)     # both resolutions occur
    assert_matches_matplotlib(SADDLE_X, SADDLE_Y, F, count)


@pytest.mark.parametrize("F", [field(lambda x, y: 1.0 + x ** 2 + y ** 2),
                               field(lambda x, y: -1.0 - x ** 2 * y ** 2)])
def test_no_sign_change_gives_no_polyline(F):
    assert zero_contour(X, Y, F) == []


def test_zero_raster_points_give_no_repeated_points():
    x = 0.1 * np.arange(-10, 11)      # exact negatives: x + y = 0 on the anti-diagonal
    # Through the zero points: matplotlib reaches each along two edges.
    [line] = zero_contour(x, x, field(lambda x, y: x + y, x, x))
    [theirs] = matplotlib_contour(x, x, field(lambda x, y: x + y, x, x))
    assert np.all(np.any(np.diff(line, axis=0) != 0.0, axis=1))
    assert np.array_equal(line, theirs[np.r_[True, np.any(np.diff(theirs, axis=0), axis=1)]])
    assert np.array_equal(line[:, 0], -line[:, 1]) and len(line) == len(x)
    # A zero minimum: F <= 0 at one point only, no polyline of 2 distinct points.
    assert zero_contour(x, x, field(lambda x, y: x ** 2 + y ** 2, x, x)) == []


def test_shape_is_checked():
    with pytest.raises(ValueError, match="shape"):
        zero_contour(X, Y, field(lambda x, y: x).T)
