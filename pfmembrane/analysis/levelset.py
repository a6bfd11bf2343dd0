"""The sharp-interface limit of phase-field checkpoints.

Compares a phase-field solution with the axisymmetric Canham-Helfrich shape
of the same scene (`pfmembrane.sharp`): the relative energy error, the
distance between the zero level set of phi_h and the sharp generating curve
(Figure 8b of the paper), the Canham-Helfrich energy of that level set, and
the extrapolation of the energies to eps -> 0.

Command line::

    python -m pfmembrane.analysis.levelset CHECKPOINT.h5 [more.h5 ...] --out runs/limit/NAME

writes ``NAME.md`` (one row per checkpoint, and the extrapolated energy when
the checkpoints share one scene and hold at least three distinct eps) and
``NAME.png`` (the zero level sets on the sharp curve, and their signed
distance to it along the curve).

Lengths are in the units of the scene (those of the radius R and the box).
"""

import argparse
import os
import sys
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from pfmembrane.io import checkpoint
from pfmembrane.io.options import targets
from pfmembrane.sharp import solver as sharp
from pfmembrane.analysis.contour import zero_contour
from pfmembrane.kernels.basis import folded_basis, locality
from pfmembrane.kernels.maxent import interpolate
from pfmembrane.kernels.nodes import raster_axes

# phi_h one eps inside the box above -1 + BOUNDARY_TOL: for the tanh profile the membrane is
# then within about 6 eps of the sides where phi = -1 is imposed.
BOUNDARY_TOL = 1e-3
BOUNDARY_SAMPLES = 400

__all__ = ["SCENE_ATTRS", "reference", "PhaseField", "level_set", "membrane", "level_set_energy",
           "loop_energy", "Component", "components_energy", "distance",
           "Feature", "smallest_feature",
           "compare", "Extrapolation", "extrapolate", "main"]

# Attributes a checkpoint needs, beyond nodes and phi, for `compare`.
SCENE_ATTRS = ("branch", "reduced_volume", "c0", "radius", "k", "gamma",
               "cutoff", "box", "energy")
_SEED_STEP = 1.0         # raster spacing of the seed contour, in units of eps
_NEWTON_STEPS = 20       # projections onto phi_h = 0; 3-5 suffice
_NEWTON_TOL = 1e-10      # last step, relative to the box size
_TOPOLOGY_TOL = 1e-3     # an end this close to the axis (or to the other end), box units
_DENSE = 16              # spline points per polyline segment in `distance`
# The level set's points: its energy's sine modes (`sharp.shape_energy`) take a quarter of them
# at most, which a narrow neck needs (runs/limit/narrow_necks.md).
LEVEL_SET_SAMPLES = 2000
_NEAREST = 8             # vertices whose segments `distance` searches


def reference(branch, reduced_volume, c0=0.0, radius=1.0, k=1.0):
    """The sharp-interface shape of a scene, computed once per process.

    Not collective.  One `pfmembrane.sharp.solve` at its default resolution
    takes about 0.2 s for v = 0.8 (continuation from the sphere included)
    and 4 ms for the sphere, v = 1; later calls with the same scene return
    the same object.

    Parameters
    ----------
    branch : {'oblate', 'prolate', 'stomatocyte'}
    reduced_volume : float
        v in (0, 1].
    c0 : float
        Spontaneous curvature (inverse length).
    radius : float
        R, the radius of the sphere of the same area.
    k : float
        Bending rigidity.

    Returns
    -------
    pfmembrane.sharp.SharpShape
        Shared between callers: its curve arrays are read-only.  The curve
        is centred at z = 0 (volume centroid).
    """
    return _reference(str(branch), float(reduced_volume), float(c0),
                      float(radius), float(k))


@lru_cache(maxsize=None)
def _reference(branch, reduced_volume, c0, radius, k):
    shape = sharp.solve(reduced_volume, branch, c0=c0, radius=radius, k=k)
    shape.r.setflags(write=False)
    shape.z.setflags(write=False)
    return shape


class PhaseField:
    """phi_h = sum_a p_a(x) phi_a of a checkpoint, with the solver's basis.

    Not collective.  The basis is the one of
    `pfmembrane.parallel.discretization.Discretization`: the locality beta_a of the
    checkpoint's basis parameters (`kernels.basis.spacing_and_locality`,
    `io.checkpoint.basis`), its support cut-off, and the nodes within a
    support radius of the axis mirrored to r < 0 with their original's
    value, so that phi_h is even in r.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint or alike
        Needs ``nodes``, ``phi`` and ``attrs['gamma']``.
    beta : ndarray, optional
        The locality of these nodes, if the caller has it (another field
        on the same nodes): the nodal spacing is the costly part.
    """

    def __init__(self, ckpt, beta=None):
        b = checkpoint.basis(ckpt.attrs)
        self.cutoff = b["cutoff"]
        self.nodes, self.phi = ckpt.nodes, np.asarray(ckpt.phi)
        self.beta = beta if beta is not None else locality(
            ckpt.nodes, b["gamma"], b["spacing_smoothing"], floor=b["spacing_floor"])

    def __call__(self, points, gradient=False):
        """phi_h at `points`, shape (M, 2), in the hull of the mirrored nodes.

        Returns
        -------
        phi : ndarray, shape (M,)
        grad : ndarray, shape (M, 2)
            (d/dr, d/dz) of phi_h; only if `gradient`.
        """
        basis = folded_basis(points, self.nodes, self.beta, self.cutoff,
                             derivatives=int(gradient))
        phi = interpolate(basis, self.phi)
        if not gradient:
            return phi
        grad = np.column_stack([interpolate(basis._replace(p=basis.dp[:, i]),
                                            self.phi) for i in range(2)])
        return phi, grad


def level_set(ckpt, samples=LEVEL_SET_SAMPLES, field=None):
    """The membrane phi_h = 0 of a checkpoint as polylines in (r, z).

    Not collective.  The phase field is the max-ent approximant phi_h, not
    the nodal values, which it does not interpolate (on a graded grid they
    can oscillate and cross zero away from the membrane).  The zero contour
    of phi_h sampled on a raster of spacing eps is resampled uniformly
    in arc length and every point is then projected onto phi_h = 0 by
    Newton steps along grad phi_h, x <- x - phi_h grad phi_h / |grad phi_h|^2.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint or alike
        See `PhaseField`.
    samples : int
        Number of points over all pieces, shared in proportion to their
        lengths (at least 2 per piece).
    field : PhaseField, optional
        phi_h of `ckpt`, if the caller has built it already.

    Returns
    -------
    list of ndarray, shape (M, 2)
        One polyline per connected piece; the points satisfy phi_h = 0 to
        a last Newton step below 1e-10 of the box size.

    Raises
    ------
    ValueError
        If phi_h has no zero contour.
    RuntimeError
        If the projection does not converge.
    """
    field = PhaseField(ckpt) if field is None else field
    pieces = _raster_contour(field, np.asarray(ckpt.attrs["box"], dtype=float),
                             _SEED_STEP * float(ckpt.attrs["eps"]))
    if not pieces:
        raise ValueError("the phase field has no zero level set")
    lengths = np.array([_arc_length(piece)[-1] for piece in pieces])
    counts = np.maximum(2, np.rint(samples * lengths / lengths.sum())).astype(int)
    points = np.vstack([_resample(piece, count)
                        for piece, count in zip(pieces, counts)])
    scale = _NEWTON_TOL * np.max(np.asarray(ckpt.attrs["box"], dtype=float))
    for _ in range(_NEWTON_STEPS):
        phi, grad = field(points, gradient=True)
        step = (phi / np.sum(grad ** 2, axis=1))[:, None] * grad
        points -= step
        # phi_h is even in r: a point pushed across the axis by rounding
        # has the same value at its mirror image in the half-plane.
        points[:, 0] = np.abs(points[:, 0])
        if np.max(np.hypot(*step.T)) < scale:
            return np.split(points, np.cumsum(counts)[:-1])
    raise RuntimeError(f"the projection onto phi_h = 0 did not converge in "
                       f"{_NEWTON_STEPS} Newton steps")


def membrane(ckpt, samples=LEVEL_SET_SAMPLES, field=None):
    """`level_set`, or [] where phi_h has no zero level set or the projection
    onto it fails: for what draws or measures a membrane that may be absent.

    Not collective.
    """
    try:
        return level_set(ckpt, samples, field)
    except (ValueError, RuntimeError):
        return []


def topology(curve, box):
    """The surfaces of revolution of a level set (`level_set` on the full box).

    Not collective. A piece from the axis to the axis revolves into a sphere
    (genus 0), a closed piece off the axis into a torus (genus 1); a piece
    that ends elsewhere leaves through the box. Returns a dict: ``spheres``,
    ``tori``, ``open`` (pieces through the box), ``components`` (their sum)
    and ``label`` (e.g. "1 sphere", "2 spheres", "1 torus").
    """
    tol = _TOPOLOGY_TOL * max(box)
    counts = {'spheres': 0, 'tori': 0, 'open': 0}
    for piece in curve:
        ends = piece[[0, -1]]
        if np.all(ends[:, 0] < tol):
            counts['spheres'] += 1
        elif np.hypot(*(ends[0] - ends[1])) < tol and piece[:, 0].min() > tol:
            counts['tori'] += 1
        else:
            counts['open'] += 1
    counts['components'] = sum(counts.values())
    names = ((counts['spheres'], 'sphere', 'spheres'), (counts['tori'], 'torus', 'tori'),
             (counts['open'], 'open piece', 'open pieces'))
    counts['label'] = ' + '.join(f"{n} {one if n == 1 else many}"
                                 for n, one, many in names if n) or 'none'
    return counts


# `smallest_feature`: two points of a curve are a gap's when they lie more than GAP_ARC times
# their distance apart along it (neighbours along the curve are never), and a local minimum
# of r is a neck when r rises on both sides by NECK_RISE of it (or of the curve's extent
# times 1e-3) before it falls below it again (scipy's prominence).
GAP_ARC = 3.0
NECK_RISE = 0.05
FEATURE_SAMPLES = 1000


class Feature(NamedTuple):
    """The smallest feature of a meridian curve (`smallest_feature`).

    Attributes
    ----------
    size : float
        Its width, in the units of the curve.
    kind : str
        'neck' (twice a local minimum of r along a piece), 'gap' (the distance
        between two points far apart along the curve), 'hole' (twice the
        smallest r of a closed loop off the axis: a torus's hole), or, where
        the curve has none of those narrower, 'diameter' (a piece from the axis
        to the axis: the smaller of 2 max r and its height) or 'tube' (a loop:
        the smaller of its width and height).
    where : ndarray, shape (2,)
        (r, z) of it: the neck's or the hole's point of the curve, the middle
        of a gap's two points, the middle of a piece's bounding box.
    """

    size: float
    kind: str
    where: np.ndarray


def smallest_feature(curve, samples=FEATURE_SAMPLES, gap_arc=GAP_ARC):
    """The narrowest thing of a meridian curve that an interface of width ~eps
    must resolve: the smallest of its necks, gaps and holes (`Feature`).

    Not collective. `curve` is a list of polylines (M, 2) in (r, z) as
    `level_set` returns them, or one curve: an (M, 2) array or an (r, z)
    pair of arrays (a sharp shape's generating curve from the axis to the
    axis). A piece whose ends meet off the axis is a closed loop (a torus's
    section). The pieces are resampled uniformly in arc length, `samples`
    points over all of them, and

    - a neck is a local minimum of r along a piece (not a closed loop), away
      from its ends, that r rises from on both sides by NECK_RISE of it: its
      width 2 r (the pinch of a stomatocyte's or a dumbbell's neck);
    - a gap is the smallest distance d between two points of the curve more
      than `gap_arc` d apart along it (on different pieces: any two), found
      with a `cKDTree` (pairs within a radius doubled until one qualifies):
      a stomatocyte's outer and inner membranes, a bud and its mother, a
      discocyte's dimple; neighbours along a curve, and the two sides of a
      fold, are no gap (a semicircle's ends lie pi/2 d apart);
    - a hole is twice the smallest r of a closed loop (a torus's hole).

    Without any of those narrower, a piece's own size: a circle's diameter.
    Returns a `Feature` (size, kind, where); lengths in the curve's units.
    """
    pieces = _feature_pieces(curve)
    if not pieces:
        raise ValueError("no curve to measure")
    extent = float(np.ptp(np.vstack(pieces), axis=0).max())
    lengths = np.array([_arc_length(p)[-1] for p in pieces])
    closes = 1e-6 * max(extent, np.finfo(float).tiny)
    closed = [bool(np.hypot(*(p[0] - p[-1])) < max(closes, 1e-3 * extent)
                   and p[:, 0].min() > 1e-3 * extent) for p in pieces]
    h = lengths.sum() / samples
    points, ids, arcs = [], [], []
    for k, (piece, length) in enumerate(zip(pieces, lengths)):
        count = max(3, int(np.ceil(length / h)) + 1)
        points.append(_resample(piece, count))
        ids.append(np.full(count, k))
        arcs.append(np.linspace(0.0, length, count))
    found = []
    for piece, loop in zip(points, closed):
        r = piece[:, 0]
        box = 0.5 * (piece.min(axis=0) + piece.max(axis=0))
        if loop:
            i = int(np.argmin(r))
            found.append(Feature(2.0 * float(r[i]), 'hole', piece[i].copy()))
            found.append(Feature(float(np.ptp(piece, axis=0).min()), 'tube', box))
            continue
        found.append(Feature(float(min(2.0 * r.max(), np.ptp(piece[:, 1]))), 'diameter', box))
        necks = _necks(r, 1e-3 * extent)
        if necks.size:
            i = int(necks[np.argmin(r[necks])])
            found.append(Feature(2.0 * float(r[i]), 'neck', piece[i].copy()))
    gap = _smallest_gap(np.vstack(points), np.concatenate(ids), np.concatenate(arcs),
                        lengths, np.array(closed), h, extent, gap_arc)
    if gap is not None:
        found.append(gap)
    return min(found, key=lambda f: f.size)


def _feature_pieces(curve):
    """`smallest_feature`'s curve as a list of (M, 2) float arrays of two points or more."""
    if isinstance(curve, tuple) and len(curve) == 2 and np.ndim(curve[0]) == 1:
        curve = [np.column_stack([np.asarray(curve[0], float), np.asarray(curve[1], float)])]
    elif isinstance(curve, np.ndarray) and curve.ndim == 2:
        curve = [curve]
    pieces = []
    for piece in curve:
        piece = np.asarray(piece, dtype=float)
        keep = np.concatenate([[True], np.hypot(*np.diff(piece, axis=0).T) > 0])
        if keep.sum() >= 2:
            pieces.append(piece[keep])
    return pieces


def _necks(r, floor):
    """Indices of the local minima of r along an open piece that r rises from on both
    sides by NECK_RISE of it (at least `floor`) before it falls below it again."""
    from scipy.signal import find_peaks
    peaks, props = find_peaks(-r, prominence=0.0)
    if not peaks.size:
        return peaks
    keep = (props['prominences'] >= np.maximum(NECK_RISE * r[peaks], floor)) & (r[peaks] > floor)
    return peaks[keep]


def _smallest_gap(points, ids, arcs, lengths, closed, h, extent, gap_arc):
    """The gap `Feature` of resampled points (their piece and arc length), or None."""
    tree = cKDTree(points)
    radius = 4.0 * h
    while True:
        pairs = tree.query_pairs(radius, output_type='ndarray')
        if len(pairs):
            i, j = pairs.T
            d = np.hypot(*(points[i] - points[j]).T)
            along = np.abs(arcs[i] - arcs[j])
            loop = closed[ids[i]]
            along = np.where(loop, np.minimum(along, lengths[ids[i]] - along), along)
            along = np.where(ids[i] == ids[j], along, np.inf)
            ok = along > gap_arc * d
            if ok.any():
                m = np.flatnonzero(ok)[np.argmin(d[ok])]
                return Feature(float(d[m]), 'gap', 0.5 * (points[i[m]] + points[j[m]]))
        if radius > 2.0 * extent:
            return None
        radius *= 2.0


def up_down_asymmetry(curve, radius):
    """(largest r of a level set above the middle of its height) - (that below), over
    `radius`: 0 on an up-down symmetric shape, its sign telling a pear from its mirror
    image. Not collective."""
    points = np.vstack(curve)
    middle = 0.5 * (points[:, 1].max() + points[:, 1].min())
    return (points[points[:, 1] > middle, 0].max()
            - points[points[:, 1] < middle, 0].max()) / radius


def level_set_energy(ckpt, curve, field=None):
    """Canham-Helfrich energy of the membrane phi_h = 0, put on the
    constraints of the scene (`pfmembrane.sharp.shape_energy`).

    Not collective.  The tangent angle comes from grad phi_h at the points
    of the level set, the arc length from the polyline.  The level set lies
    a distance d = O(eps) from the sharp shape, so this energy approaches
    the sharp one as d^2, much faster than the phase-field energy.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint or alike
        See `compare`; the area and volume are those its ``radius`` and
        ``reduced_volume`` fix, so a scene without a sharp shape has one too.
    curve : list of ndarray
        The level set of `ckpt` (`level_set`).
    field : PhaseField, optional
        phi_h of `ckpt`, if the caller has built it already.

    Returns
    -------
    energy, energy_curve : float
        As `pfmembrane.sharp.shape_energy` (its sine modes as many as the
        curve needs); NaN unless the level set is one curve from the axis to
        the axis.
    """
    attrs = ckpt.attrs
    tolerance = 1e-6 * np.max(np.asarray(attrs["box"], dtype=float))
    if len(curve) != 1 or max(curve[0][0, 0], curve[0][-1, 0]) > tolerance:
        return np.nan, np.nan
    points = curve[0] if curve[0][0, 1] < curve[0][-1, 1] else curve[0][::-1]
    _, grad = (PhaseField(ckpt) if field is None else field)(points, gradient=True)
    if not np.all(np.isfinite(grad)):
        return np.nan, np.nan
    # phi_h > 0 inside: the inward normal grad phi_h turned clockwise is the
    # tangent of the counterclockwise meridian, bottom pole to top pole.
    psi = np.unwrap(np.arctan2(-grad[:, 0], grad[:, 1]))
    psi -= 2.0 * np.pi * np.round(psi[0] / (2.0 * np.pi))
    s = _arc_length(points)
    area, volume = targets(float(attrs["radius"]), float(attrs["reduced_volume"]))
    return sharp.shape_energy(np.pi * s / s[-1], psi, s[-1], area, volume,
                              float(attrs["c0"]), float(attrs["k"]))


LOOP_MODES = 48  # Fourier modes of the tangent angle in `loop_energy`


def loop_energy(ckpt, piece, field=None, modes=LOOP_MODES):
    """Canham-Helfrich energy (k/2) int (H - C0)^2 dA of the torus that a
    closed level-set piece off the axis revolves into (`topology`: a torus).

    Not collective. Unlike `level_set_energy` (one curve from the axis to the
    axis), the piece is taken as it is, not put on the scene's constraints:
    at C0 = 0 the energy depends on the reduced volume only, and at a
    stationary shape (the Clifford torus) only to second order. The tangent
    angle psi comes from grad phi_h, as there, smoothed by a Fourier series
    of `modes` modes in arc length; H = (psi_s + sin psi / r) / 2 on the loop
    turned counterclockwise (inside on the left).

    Returns
    -------
    energy : float
    radii : tuple of float
        (tube, centre line): half the loop's width in r, and the mean of its
        extreme r.
    """
    attrs = ckpt.attrs
    points = piece[:-1] if np.allclose(piece[0], piece[-1]) else piece
    r, z = points.T
    if np.sum(r * np.roll(z, -1) - np.roll(r, -1) * z) < 0:  # clockwise: turn it
        points = points[::-1]
    _, grad = (PhaseField(ckpt) if field is None else field)(points, gradient=True)
    seg = np.hypot(*np.diff(np.vstack([points, points[:1]]), axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length, s = s[-1], s[:-1]
    psi = np.unwrap(np.arctan2(-grad[:, 0], grad[:, 1]))
    # psi gains 2 pi round the loop: fit the periodic rest.
    t = 2.0 * np.pi * s / length
    k = np.arange(1, modes + 1)
    basis = np.hstack([np.ones((t.size, 1)), np.cos(np.outer(t, k)), np.sin(np.outer(t, k))])
    coef = np.linalg.lstsq(basis, psi - t, rcond=None)[0]
    slope = np.hstack([np.zeros((t.size, 1)), -k * np.sin(np.outer(t, k)),
                       k * np.cos(np.outer(t, k))])
    psi_s = (1.0 + slope @ coef) * 2.0 * np.pi / length
    psi = t + basis @ coef
    r = points[:, 0]
    h = 0.5 * (psi_s + np.sin(psi) / r) - float(attrs["c0"])
    ds = 0.5 * (seg + np.roll(seg, 1))  # trapezoid weights of the closed polyline
    energy = np.pi * float(attrs["k"]) * np.sum(r * h * h * ds)
    return float(energy), (0.5 * float(np.ptp(r)), 0.5 * float(r.max() + r.min()))


class Component(NamedTuple):
    """One surface of a level set (`components_energy`).

    Attributes
    ----------
    kind : str
        'sphere' (a piece from the axis to the axis), 'torus' (a closed
        loop off the axis) or 'open' (a piece through the box).
    orientation : int
        +1 where phi_h > 0 lies inside the surface (a vesicle), -1 where it
        lies outside (a hole of phi_h < 0 inside the vesicle, as the inner
        sphere of a nested pair); 0 for an open piece.
    energy : float
        (k/2) int (H - C0)^2 dA of the surface, H the mean curvature for the
        outward normal of phi_h > 0; NaN for an open piece.
    """

    kind: str
    orientation: int
    energy: float


ORIENTATION_OFFSET = 0.5  # phi_h is sampled this many eps off a piece, either side


def components_energy(ckpt, curve, field=None):
    """Canham-Helfrich energy of a level set of any topology, component by component.

    Not collective. The convention is `pfmembrane.sharp`'s: E = (k/2) int (H - C0)^2 dA
    with H = (c1 + c2) / 2 the mean curvature for the outward normal of the region
    phi_h > 0 (H = 1/R on a sphere of radius R holding phi_h > 0, so E = 2 pi k (1 - C0 R)^2),
    summed over the components (`topology`). Unlike `level_set_energy`, no component is put on
    the scene's area and volume (the scene constrains their sum): each is taken as it is, as
    `loop_energy` takes a torus.

    A component's orientation comes from phi_h itself: phi_h sampled `ORIENTATION_OFFSET` eps
    off the piece on either side along its normal. Where phi_h > 0 lies outside the surface
    (orientation -1, e.g. the inner sphere of a stomatocyte that has pinched off), the outward
    normal of phi_h > 0 points into it and H has the opposite sign from a free surface's: its
    energy is that of the surface with phi_h > 0 inside and C0 -> -C0. A sphere's energy is
    the one of `pfmembrane.sharp.shape_energy`'s fitted curve (the tangent angle from
    grad phi_h, as in `level_set_energy`), a torus's that of `loop_energy`.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint or alike
        ``nodes``, ``phi`` and the attributes ``c0``, ``k``, ``eps``, ``box``, ``gamma``.
    curve : list of ndarray
        The level set of `ckpt` on the full box (`level_set`).
    field : PhaseField, optional
        phi_h of `ckpt`, if the caller has built it already.

    Returns
    -------
    energy : float
        The sum over the components; NaN if a piece is open or a component's energy is not
        finite.
    components : list of Component
        In the order of `curve`.
    """
    attrs = ckpt.attrs
    field = PhaseField(ckpt) if field is None else field
    tol = _TOPOLOGY_TOL * np.max(np.asarray(attrs["box"], dtype=float))
    delta = ORIENTATION_OFFSET * float(attrs["eps"])
    c0, k = float(attrs["c0"]), float(attrs["k"])
    components = []
    for piece in curve:
        kind = topology([piece], attrs["box"])
        kind = 'sphere' if kind['spheres'] else 'torus' if kind['tori'] else 'open'
        if kind == 'open':
            components.append(Component(kind, 0, np.nan))
            continue
        if kind == 'sphere':  # bottom pole to top pole: counterclockwise
            points = piece if piece[0, 1] < piece[-1, 1] else piece[::-1]
        else:
            points = piece[:-1] if np.hypot(*(piece[0] - piece[-1])) < tol else piece
            r, z = points.T
            if np.sum(r * np.roll(z, -1) - np.roll(r, -1) * z) < 0:
                points = points[::-1]
        orientation = _orientation(field, points, delta, closed=kind == 'torus')
        if orientation == 0:
            components.append(Component(kind, 0, np.nan))
            continue
        # phi_h > 0 outside: the surface with orientation * phi_h > 0 inside and C0 -> -C0.
        oriented = field if orientation > 0 else _Negated(field)
        if kind == 'sphere':
            energy = _sphere_energy(points, oriented, orientation * c0, k)
        else:
            flipped = _Attrs(dict(attrs, c0=orientation * c0))
            energy = loop_energy(flipped, points, oriented)[0]
        components.append(Component(kind, orientation, float(energy)))
    return float(sum(c.energy for c in components)), components


def _orientation(field, points, delta, closed):
    """+1 if phi_h is larger just inside the counterclockwise `points` (the surface's
    side) than just outside, -1 if smaller, 0 if undecided."""
    ends = np.vstack([points[-1:], points, points[:1]]) if closed else points
    tangent = np.gradient(ends, axis=0)[1:-1] if closed else np.gradient(ends, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # outward, right of the tangent
    normal /= np.maximum(np.hypot(*normal.T), np.finfo(float).tiny)[:, None]
    # Off the axis, where the offset points stay in the half-plane.
    far = points[:, 0] > 2.0 * delta
    if np.count_nonzero(far) >= 3:
        points, normal = points[far], normal[far]
    difference = field(points - delta * normal) - field(points + delta * normal)
    return int(np.sign(np.median(difference)))


def _sphere_energy(points, field, c0, k):
    """(k/2) int (H - c0)^2 dA of the counterclockwise piece from the axis to the axis,
    `field` > 0 inside: the energy of `pfmembrane.sharp.shape_energy`'s fitted curve."""
    _, grad = field(points, gradient=True)
    if not np.all(np.isfinite(grad)):
        return np.nan
    psi = np.unwrap(np.arctan2(-grad[:, 0], grad[:, 1]))
    psi -= 2.0 * np.pi * np.round(psi[0] / (2.0 * np.pi))
    s = _arc_length(points)
    # Its own area and volume: the projection `shape_energy` adds is not used.
    area = 2.0 * np.pi * _trapezoid_weights(points) @ points[:, 0]
    volume = enclosed_volume([points])
    return sharp.shape_energy(np.pi * s / s[-1], psi, s[-1], area, volume, c0, k)[1]


class _Negated:
    """-phi_h (and -grad phi_h) of a `PhaseField`."""

    def __init__(self, field):
        self.field = field

    def __call__(self, points, gradient=False):
        if not gradient:
            return -self.field(points)
        phi, grad = self.field(points, gradient=True)
        return -phi, -grad


class _Attrs(NamedTuple):
    """A checkpoint stand-in with attributes only (for `loop_energy` with a field)."""

    attrs: dict


def _raster_contour(field, box, step):
    """Polylines of the zero contour of `field` on a raster of the box."""
    r, z = raster_axes(box, step)
    R, Z = np.meshgrid(r, z)
    phi = field(np.column_stack([R.ravel(), Z.ravel()])).reshape(R.shape)
    if not phi.min() < 0.0 < phi.max():
        # No sign change, no membrane: where phi_h >= 0 touches 0, zero_contour
        # would still trace loops around the zero raster points.
        return []
    return zero_contour(r, z, phi)


def distance(curve, shape, centre=0.0):
    """Distances between a phase-field level set and a sharp-interface curve.

    Not collective.  Both curves are refined by cubic splines in chord
    length (`_DENSE` points per segment), so that the distances do not see
    the chords between the points.

    Parameters
    ----------
    curve : sequence of ndarray, shape (M, 2)
        Polylines in (r, z), e.g. from `level_set`.
    shape : pfmembrane.sharp.SharpShape
        Its generating curve is centred at z = 0.
    centre : float
        Height to which the sharp curve is shifted: Zb / 2 for a checkpoint.

    Returns
    -------
    dict
        ``max`` and ``mean`` (weighted by arc length) over the points of
        `curve` of their distance to the sharp curve, and ``hausdorff``,
        the symmetric Hausdorff distance.
    """
    target = _dense(np.column_stack([shape.r, shape.z + centre]))
    pieces = [np.asarray(piece, dtype=float) for piece in curve]
    near = [_polyline_distance(piece, target) for piece in pieces]
    back = np.min([_polyline_distance(target, _dense(piece))
                   for piece in pieces], axis=0)
    weights = [_trapezoid_weights(piece) for piece in pieces]
    return {"max": float(max(np.max(d) for d in near)),
            "mean": float(sum(w @ d for w, d in zip(weights, near))
                          / sum(np.sum(w) for w in weights)),
            "hausdorff": float(max(max(np.max(d) for d in near),
                                   np.max(back)))}


def boundary_phi(ckpt, samples=BOUNDARY_SAMPLES, field=None):
    """Largest phi_h on the lines one eps inside the sides r = Rb, z = 0, z = Zb.

    Not collective. The nodes on those sides hold phi = -1 by construction; one eps inside,
    phi_h shows a membrane pressed against the box. `ckpt` covers the full box;
    `field`, if given, is its phi_h (`PhaseField`).
    """
    rb, zb = ckpt.box
    d = float(ckpt.attrs['eps'])
    s = np.linspace(0.0, 1.0, samples)
    points = np.concatenate([np.column_stack([s * (rb - d), np.full(samples, d)]),
                             np.column_stack([s * (rb - d), np.full(samples, zb - d)]),
                             np.column_stack([np.full(samples, rb - d), d + s * (zb - 2 * d)])])
    return float(np.max((PhaseField(ckpt) if field is None else field)(points)))


def enclosed_volume(curve):
    """Volume of the solid of revolution inside a level set.

    Not collective. Each polyline of `curve` (from `level_set`) runs from the
    axis to the axis, or is a loop off it; closing it adds nothing along
    r = 0, so its volume is |pi int r^2 dz|, exact for straight segments.
    The pieces' volumes are summed (no piece lies inside another).
    """
    total = 0.0
    for piece in curve:
        r, z = np.vstack([piece, piece[:1]]).T
        total += abs(np.pi * np.sum((r[1:] ** 2 + r[1:] * r[:-1] + r[:-1] ** 2) / 3 * np.diff(z)))
    return total


def revolved_area(curve):
    """Area of the surface of revolution of a level set: 2 pi int r ds over
    its polylines (`level_set`), exact for straight segments (frusta), a
    loop closed. Not collective."""
    total = 0.0
    for piece in curve:
        loop = piece[0, 0] > 0 and not np.allclose(piece[0], piece[-1])
        r, z = (np.vstack([piece, piece[:1]]) if loop else piece).T
        total += np.pi * np.sum((r[1:] + r[:-1]) * np.hypot(np.diff(r), np.diff(z)))
    return total


def compare(ckpt, samples=LEVEL_SET_SAMPLES, field=None, curve=None):
    """Energy and shape of a checkpoint against its sharp-interface limit.

    Not collective.  The sharp shape (`reference`) has the scene of the
    checkpoint: branch, reduced volume, c0, radius and k; its curve is
    placed at the centre z = Zb / 2 of the box, where the moment
    constraint holds the vesicle.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint or alike
        ``nodes``, ``phi`` and the attributes `SCENE_ATTRS`.
    samples : int
        Points of the level set, see `level_set`.
    field : PhaseField, optional
        phi_h of `ckpt`, if the caller has built it already.
    curve : list of ndarray, optional
        Its `level_set`, likewise.

    Returns
    -------
    dict
        ``energy_sharp``; ``rel_error`` = (E - E_sharp) / E_sharp, signed;
        ``energy_level_set`` (`level_set_energy`) and its
        ``rel_error_level_set``; ``dist_max``, ``dist_mean``,
        ``dist_hausdorff``: see `distance`.

    Raises
    ------
    ValueError
        If an attribute is missing, the scene has no sharp counterpart,
        phi_h has no zero level set or one that is not one sphere
        (`topology`: the sharp shapes are).
    RuntimeError
        If the projection onto the level set does not converge (`level_set`).
    """
    return _compare(ckpt, samples, field, curve)[0]


def _compare(ckpt, samples, field=None, curve=None):
    """`compare`, and the level set and the placed sharp curve it measured."""
    attrs = ckpt.attrs
    missing = [key for key in SCENE_ATTRS if key not in attrs]
    if missing:
        raise ValueError(f"checkpoint lacks the attribute(s) "
                         f"{', '.join(missing)}")
    shape = reference(*_scene(attrs))
    field = PhaseField(ckpt) if field is None else field
    curve = level_set(ckpt, samples, field) if curve is None else curve
    found = topology(curve, np.asarray(attrs["box"], dtype=float))
    if found['label'] != '1 sphere':
        raise ValueError(f"phi_h = 0 is {found['label']}, the sharp shape one sphere: "
                         "no comparison across topologies")
    centre = 0.5 * float(attrs["box"][1])
    dist = distance(curve, shape, centre)
    level_energy = level_set_energy(ckpt, curve, field)[0]
    result = {"energy_sharp": shape.energy,
              "rel_error": (float(attrs["energy"]) - shape.energy) / shape.energy,
              "energy_level_set": level_energy,
              "rel_error_level_set": (level_energy - shape.energy) / shape.energy,
              "dist_max": dist["max"], "dist_mean": dist["mean"],
              "dist_hausdorff": dist["hausdorff"]}
    return result, curve, _dense(np.column_stack([shape.r, shape.z + centre]))


class Extrapolation(NamedTuple):
    """The fit E(eps) = E0 + a1 eps + a2 eps^2 and its limit eps -> 0.

    Attributes
    ----------
    e0 : float
        Extrapolated energy E0.
    error : float
        Error estimate of `e0`: ``abs(e0 - e0_linear)`` plus, with four
        or more distinct eps, ``abs(e0 - e0_reduced)``.
    coefficients : ndarray
        (E0, a1, a2).
    residual : float
        Root mean square residual of the fit; 0 with three points.
    e0_linear : float
        E0 of the line E0 + a1 eps fitted to the two smallest eps.
    e0_reduced : float
        E0 of the quadratic fitted without the largest eps; NaN with three
        distinct eps.
    """

    e0: float
    error: float
    coefficients: np.ndarray
    residual: float
    e0_linear: float
    e0_reduced: float


def extrapolate(eps, energy):
    """Extrapolate phase-field energies to eps -> 0.

    Not collective.  Least squares fit of E(eps) = E0 + a1 eps + a2 eps^2
    (exact through three points).  The error estimate adds the changes of
    E0 under the two perturbations of the fit that the data allow:

    - one order less: the line through the two smallest eps.  Its own
      error is about |a2| eps_1 eps_2, which exceeds that of the quadratic
      (about |a3| eps_1 eps_2 eps_3) as long as the terms of the expansion
      decrease, so this term is conservative in the asymptotic range;
    - one point less (four or more distinct eps): the quadratic without
      the largest eps, which measures how far the quadratic model holds
      over the range of the data, scatter included.

    The estimate cannot detect energies outside the asymptotic range.  On
    the paper's uniform 296,344-node discocyte energies (Table 1; sharp
    energy 9.12657) it covers the error for eps = 0.03, 0.02, 0.01
    (9.1434 +- 0.054, true error +0.017), 0.04 ... 0.01 (9.1141 +- 0.054,
    -0.012) and 0.05 ... 0.01 (9.0714 +- 0.061, -0.055), but not for
    eps = 0.04, 0.03, 0.02 (9.0262 +- 0.045, -0.100), 0.05 ... 0.02
    (8.9446 +- 0.118, -0.182) or 0.05, 0.04, 0.03 (8.7751 +- 0.16, -0.35),
    where the cubic and higher terms are not small.  On E0 + a1 eps + a2 eps^2 + a3 eps^3 with |a3| eps <~ a2 it is
    1 to 7 times the error.

    Parameters
    ----------
    eps : array_like, shape (n,)
        Regularization widths; at least three distinct values.
    energy : array_like, shape (n,)
        Phase-field energies at `eps`.

    Returns
    -------
    Extrapolation

    Raises
    ------
    ValueError
        With fewer than three distinct eps or mismatched lengths.
    """
    eps = np.asarray(eps, dtype=float)
    energy = np.asarray(energy, dtype=float)
    if eps.shape != energy.shape or eps.ndim != 1:
        raise ValueError("eps and energy must be 1-D arrays of one length")
    levels = np.unique(eps)
    if levels.size < 3:
        raise ValueError(f"extrapolation needs three distinct eps, got "
                         f"{levels.tolist()}")
    coefficients, residual = _fit(eps, energy, 2)
    e0 = coefficients[0]
    smallest = eps <= levels[1]
    e0_linear = _fit(eps[smallest], energy[smallest], 1)[0][0]
    e0_reduced = np.nan
    error = abs(e0 - e0_linear)
    if levels.size > 3:
        kept = eps < levels[-1]
        e0_reduced = _fit(eps[kept], energy[kept], 2)[0][0]
        error += abs(e0 - e0_reduced)
    return Extrapolation(float(e0), float(error), coefficients,
                         float(residual), float(e0_linear), float(e0_reduced))


def _fit(eps, energy, degree):
    """Least squares polynomial coefficients (ascending) and rms residual."""
    matrix = np.vander(eps, degree + 1, increasing=True)
    coefficients = np.linalg.lstsq(matrix, energy, rcond=None)[0]
    return coefficients, np.sqrt(np.mean((matrix @ coefficients - energy) ** 2))


def _arc_length(polyline):
    """Cumulative arc length at the vertices of a polyline."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(polyline, axis=0).T))])


def _trapezoid_weights(polyline):
    """Weights of the trapezoidal rule in arc length at the vertices."""
    half = 0.5 * np.hypot(*np.diff(polyline, axis=0).T)
    return np.concatenate([half, [0.0]]) + np.concatenate([[0.0], half])


def _resample(polyline, count):
    """`count` points uniformly spaced in arc length along a polyline."""
    s = _arc_length(polyline)
    t = np.linspace(0.0, s[-1], count)
    return np.column_stack([np.interp(t, s, polyline[:, i]) for i in range(2)])


def _dense(polyline):
    """A polyline refined `_DENSE` times by a cubic spline in chord length."""
    s = _arc_length(polyline)
    # The spline needs increasing abscissae: repeated points are dropped.
    keep = np.concatenate([[True], np.diff(s) > 0.0])
    s, polyline = s[keep], polyline[keep]
    if len(s) < 2:
        return polyline
    # Every segment is split evenly, so that the vertices stay on the result.
    fraction = np.arange(_DENSE) / _DENSE
    t = np.append((s[:-1, None] + fraction * np.diff(s)[:, None]).ravel(), s[-1])
    return CubicSpline(s, polyline)(t)


def _polyline_distance(points, polyline):
    """Distance from each point to a polyline.

    Only the segments at the `_NEAREST` vertices closest to a point are
    searched: on a polyline as dense as `_dense` makes them, the nearest
    segment is among them unless the curve returns within a few vertex
    spacings of itself.
    """
    k = min(_NEAREST, len(polyline))
    vertices = cKDTree(polyline).query(points, k=k)[1].reshape(len(points), k)
    # Segment j joins vertices j and j + 1: both segments at each vertex.
    segments = np.clip(np.concatenate([vertices - 1, vertices], axis=1),
                       0, len(polyline) - 2)
    a, b = polyline[segments], polyline[segments + 1]
    ab = b - a
    length2 = np.maximum(np.sum(ab ** 2, axis=2), np.finfo(float).tiny)
    p = points[:, None, :]
    t = np.clip(np.sum((p - a) * ab, axis=2) / length2, 0.0, 1.0)
    return np.sqrt(np.min(np.sum((p - a - t[:, :, None] * ab) ** 2, axis=2), axis=1))


def main(argv=None):
    """Write NAME.md and NAME.png for the given checkpoints.

    Not collective.

    Parameters
    ----------
    argv : list of str, optional
        Command line arguments; ``sys.argv[1:]`` by default.

    Returns
    -------
    int
        Exit status: 0 on success, 1 if a checkpoint cannot be read or has
        no sharp counterpart.
    """
    args = _parser().parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    try:
        ckpts = [checkpoint.read(path).unfolded() for path in args.checkpoints]
        rows = [_row(path, ckpt, args.samples)
                for path, ckpt in zip(args.checkpoints, ckpts)]
    except (checkpoint.CheckpointError, ValueError, RuntimeError) as exc:
        print(f"pfmembrane.analysis.levelset: error: {exc}", file=sys.stderr)
        return 1
    directory = os.path.dirname(os.path.abspath(args.out))
    os.makedirs(directory, exist_ok=True)
    with open(args.out + ".md", "w", encoding="utf-8") as stream:
        stream.write("\n".join(_report(args, rows)) + "\n")
    figure = _figure(rows)
    figure.savefig(args.out + ".png", dpi=150, bbox_inches="tight")
    plt.close(figure)
    print(args.out + ".md")
    print(args.out + ".png")
    return 0


def _parser():
    parser = argparse.ArgumentParser(
        prog="python -m pfmembrane.analysis.levelset",
        description="Compare phase-field checkpoints with the sharp-interface "
                    "limit and extrapolate their energies to eps -> 0.")
    parser.add_argument("checkpoints", nargs="+", metavar="CHECKPOINT.h5")
    parser.add_argument("--out", required=True, metavar="PATH/NAME",
                        help="writes NAME.md and NAME.png")
    parser.add_argument("--samples", type=int, default=LEVEL_SET_SAMPLES,
                        help=f"points of each zero level set (default: {LEVEL_SET_SAMPLES})")
    return parser


def _scene(attrs):
    return tuple(attrs[key] for key in ("branch", "reduced_volume", "c0",
                                        "radius", "k"))


def _row(path, ckpt, samples):
    """Everything the report and the figure need about one checkpoint."""
    from matplotlib.path import Path

    result, curve, target = _compare(ckpt, samples)
    # The sharp curve closed along the axis bounds the sharp vesicle.
    inside = Path(target).contains_points
    along = [(_arc_length(piece), np.where(inside(piece), -1.0, 1.0)
              * _polyline_distance(piece, target)) for piece in curve]
    return dict(result, path=path, attrs=ckpt.attrs, nodes=len(ckpt.nodes),
                curve=curve, target=target, along=along)


def _report(args, rows):
    lines = [f"# Sharp-interface limit: {os.path.basename(args.out)}", "",
             "Generated by `python -m pfmembrane.analysis.levelset "
             + " ".join(args.checkpoints) + f" --out {args.out}`.", "",
             "E_sharp: axisymmetric Canham-Helfrich shape of the same scene "
             "(`pfmembrane.sharp`); rel error = (E - E_sharp) / E_sharp. "
             "Distances (units of the box, R = radius) from the zero level "
             "set of the max-ent interpolant phi_h to the sharp curve "
             "centred at z = Zb / 2: max and arc-length mean over the level "
             "set, and the symmetric Hausdorff distance. E(phi_h = 0): the "
             "Canham-Helfrich energy of the level set itself, put on the "
             "scene's area and volume (`level_set_energy`); it errs by "
             "O(d^2) where E errs by O(eps).", "",
             "| checkpoint | branch | v | c0 | R | eps | nodes | gamma | "
             "cut-off | converged | E | E_sharp | rel error | E(phi_h = 0) "
             "| rel error | d max | d mean | Hausdorff | d max / eps |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in rows:
        a = row["attrs"]
        lines.append(
            f"| {os.path.basename(row['path'])} | {a['branch']} "
            f"| {a['reduced_volume']:g} | {a['c0']:g} | {a['radius']:g} "
            f"| {a['eps']:g} | {row['nodes']} | {a['gamma']:g} "
            f"| {a['cutoff']:g} | {a['converged']} | {a['energy']:.6f} "
            f"| {row['energy_sharp']:.6f} | {100 * row['rel_error']:+.3f}% "
            f"| {row['energy_level_set']:.6f} | {100 * row['rel_error_level_set']:+.5f}% "
            f"| {row['dist_max']:.2e} | {row['dist_mean']:.2e} "
            f"| {row['dist_hausdorff']:.2e} | {row['dist_max'] / a['eps']:.3f} |")
    lines.append("")
    scenes = {_scene(row["attrs"]) for row in rows}
    eps = np.array([row["attrs"]["eps"] for row in rows])
    if len(scenes) > 1:
        lines.append("No extrapolation: the checkpoints belong to different "
                     "scenes.")
    elif np.unique(eps).size < 3:
        lines.append(f"No extrapolation: it needs three distinct eps, got "
                     f"{', '.join(f'{e:g}' for e in np.unique(eps))}.")
    else:
        e_sharp = rows[0]["energy_sharp"]
        lines += ["## Extrapolation eps -> 0", ""]
        lines += _extrapolation(eps, [row["attrs"]["energy"] for row in rows], e_sharp, "E")
        lines += [
            "Error estimate (see `pfmembrane.analysis.levelset.extrapolate`): |E0 - E0_linear| (line "
            "through the two smallest eps) + |E0 - E0_reduced| (quadratic without the "
            "largest eps, with four or more eps). It holds only if the energies are in the "
            "asymptotic range of the expansion, which the fit cannot check: on the paper's "
            "own finest-grid energies, eps = 0.05, 0.04, 0.03 extrapolate to 8.775 +- 0.16 "
            "against 9.12657.", ""]
        levels = [row["energy_level_set"] for row in rows]
        if np.all(np.isfinite(levels)):
            lines += _extrapolation(eps, levels, e_sharp, "E(phi_h = 0)")
    if any(row["attrs"].get("under_resolved") for row in rows):
        lines += ["", "Some checkpoints are marked under-resolved "
                      "(eps below the grid's eps_min)."]
    if not all(row["attrs"]["converged"] for row in rows):
        lines += ["", "Some checkpoints did not converge (converged = 0)."]
    return lines


def _extrapolation(eps, energies, e_sharp, name):
    """Report lines of the fit of `energies` (`extrapolate`) against E_sharp."""
    fit = extrapolate(eps, energies)
    e0, a1, a2 = fit.coefficients
    reduced = "" if np.isnan(fit.e0_reduced) else f", E0_reduced = {fit.e0_reduced:.6f}"
    return [f"Least squares {name}(eps) = E0 + a1 eps + a2 eps^2: E0 = {e0:.6f}, "
            f"a1 = {a1:.6g}, a2 = {a2:.6g}, rms residual {fit.residual:.2e}; "
            f"E0_linear = {fit.e0_linear:.6f}{reduced}.", "",
            f"**{name}: E0 = {fit.e0:.6f} +- {fit.error:.6f}**, against E_sharp = "
            f"{e_sharp:.6f}: relative error {100 * (fit.e0 - e_sharp) / e_sharp:+.4f}% "
            f"(estimate +-{100 * fit.error / e_sharp:.4f}%): E_sharp lies "
            f"{'inside' if abs(fit.e0 - e_sharp) <= fit.error else 'OUTSIDE'} "
            f"E0 +- error.", ""]


def _figure(rows):
    """Figure 8b of the paper, and the distance along each level set."""
    import matplotlib.pyplot as plt

    figure, (shapes, along) = plt.subplots(
        1, 2, figsize=(11.0, 4.8), gridspec_kw={"width_ratios": [1.0, 1.3]})
    drawn = set()
    for row in rows:
        key = _scene(row["attrs"])
        if key not in drawn:
            drawn.add(key)
            shapes.plot(*row["target"].T, color="k", linewidth=2.5,
                        label="sharp interface" if len(drawn) == 1 else None)
    for row in rows:
        label = f"eps = {row['attrs']['eps']:g}, N = {row['nodes']}"
        lines = []
        for piece in row["curve"]:
            lines += shapes.plot(*piece.T, "--", linewidth=1.2,
                                 color=lines[0].get_color() if lines else None,
                                 label=None if lines else label)
        for k, (s, d) in enumerate(row["along"]):
            along.plot(s, d, color=lines[0].get_color(),
                       label=None if k else label)
    points = np.vstack([row["target"] for row in rows]
                       + [piece for row in rows for piece in row["curve"]])
    margin = 0.1 * np.ptp(points, axis=0).max()
    shapes.set_xlim(0.0, points[:, 0].max() + margin)
    shapes.set_ylim(points[:, 1].min() - margin, points[:, 1].max() + margin)
    shapes.set_aspect("equal")
    shapes.set_xlabel("r")
    shapes.set_ylabel("z")
    shapes.set_title(r"$\phi_h = 0$ and the sharp interface")
    shapes.legend(fontsize="small")
    along.axhline(0.0, color="k", linewidth=0.5)
    along.set_xlabel("arc length along the level set (from its first end)")
    along.set_ylabel("distance to the sharp curve")
    along.set_title(r"distance of $\phi_h = 0$ to the sharp curve "
                    "(> 0 outside it)")
    along.legend(fontsize="small")
    figure.tight_layout()
    return figure


if __name__ == "__main__":
    sys.exit(main())
