"""The start of a solve: a family's initial shape (a spheroid, a torus, two
spheres, the sharp-interface shape, or with harmonics a spheroid across the
axis or a Moebius image of the Clifford torus) checked against its box, or an
earlier result's phi_h on a new grid, its tanh profile rescaled to eps."""
import math

import numpy as np

from pfmembrane.io import checkpoint
from pfmembrane.io.options import SHAPE_NAMES, STARTS_3D, UsageError, start_kind
from pfmembrane.kernels import initial
from pfmembrane.kernels.adapt import transfer

# Resampling of a sharp start's curve, in eps: its distances err by less than
# 1/64 eps on the membrane, 1% of the tanh profile's slope.
CURVE_SPACING = 1.0 / 32


# The level set's topology of each constructed start (two spheres may overlap or touch).
TOPOLOGY = {'spheroid': '1 sphere', 'across': '1 sphere', 'sharp': '1 sphere',
            'torus': '1 torus', 'moebius': '1 torus'}


def start_topology(scene, start=None, shape='auto'):
    """What the start's phi = 0 is ('1 sphere', '1 torus'; '' unknown): an earlier
    result's checked topology, or a fresh start's by its kind (`shape` the
    -pf_start choice)."""
    if start is not None:
        return start.attrs.get('topology', '')
    return TOPOLOGY.get(kind_of(scene, shape), '')


def kind_of(p, shape='auto'):
    """The kind of start -pf_start `shape` asks for (`p` a scene or `Params`): auto
    starts a torus whose harmonics hold m = 1 on the half box from the Moebius image of
    the Clifford torus with its reduced volume, where one has it (the least energy of
    genus one there, which no axisymmetric torus reaches), any other scene from its
    family's first start (`io.options.start_kind`)."""
    if shape == 'auto' and p.branch == 'torus' and p.harmonics and p.dihedral == 1 \
            and p.symmetric:
        low, high = initial.moebius_range()
        if low < p.reduced_volume < high:
            return 'moebius'
    return start_kind(p.branch, shape)


def check_run(p):
    """Refuse the options `p` (`io.options.Params`) of a fresh run whose start
    does not fit its box; a restart's box is its checkpoint's, an auto box is
    sized to fit (`Scene.sized`)."""
    if not p.restart and p.box != 'auto':
        check_fits(p)


def check_fits(p, eps=None, start=None, sharp=None):
    """The start's kind and shape (`kernels.initial.extent`: a spheroid's
    semi-axes, a torus's radii, spheres' radii and heights, or the sharp
    generating curve (r, z) about its centroid), which with a 3 eps margin must
    fit the box (`p` a `Params`, or a scene and its `eps`; `start` the
    -pf_start choice, by default `p`'s or auto). A sharp start is checked
    only with its `sharp` curve, which the layers above compute
    (`sharp_shape`): without it the shape returned is None."""
    kind = kind_of(p, start or getattr(p, 'start', 'auto'))
    if kind == 'sharp' and sharp is None:
        return kind, None
    scene = (f"-pf_radius {p.radius:g}, -pf_reduced_volume {p.reduced_volume:g}, "
             f"-pf_branch {p.branch}")
    try:
        # Floating-point trouble means no shape, as an error rather than a warning on stderr.
        with np.errstate(divide='raise', over='raise', invalid='raise', under='ignore'):
            shape = sharp if kind == 'sharp' else initial.construction(kind, p.branch, p.area,
                                                                      p.volume)
            size, why = initial.extent(kind, shape), ''
    except (ValueError, ArithmeticError) as e:
        size, why = (math.nan, math.nan), f" ({e})" if str(e) else ''
    if not all(0 < x < math.inf for x in size):
        raise UsageError(f"no {SHAPE_NAMES[kind]} has the area and volume of {scene}: "
                         f"the initial guess cannot be built{why}")
    Rb, Zb = p.box
    margin = 3.0 * (p.eps if eps is None else eps)
    r, z = size
    if r + margin > Rb or z + margin > 0.5 * Zb:
        raise UsageError(
            f"-pf_box {Rb:g},{Zb:g} cannot hold the {p.branch} vesicle of {scene} (its "
            f"{SHAPE_NAMES[kind]} start reaches r = {r:.4g}, |z - Zb/2| = {z:.4g}) with a "
            f"margin of 3 -pf_eps: need Rb >= "
            f"{r + margin:.4g}, Zb >= {2 * (z + margin):.4g}")
    return kind, shape


def start_phi(scene, grid, eps, start, shape='auto', perturb=0.0):
    """Nodal phi of the start at every node (the scene's initial `shape`, the
    -pf_start choice, or `start`'s phi_h on this grid, its tanh profile
    rescaled to `eps`), the start's multipliers (None for a fresh start) and
    whether it was solved. With harmonics, phi is (nodes x harmonics): an
    axisymmetric fresh start carries `perturb` in every harmonic m > 0."""
    if start is None:
        kind, geometry = check_fits(scene, eps, shape)
        if kind == 'across' and not scene.harmonics:
            raise UsageError("-pf_start across: a shape across the axis needs harmonics "
                             "(-pf_harmonics)")
        if kind == 'moebius' and not (scene.harmonics and scene.dihedral == 1):
            raise UsageError("-pf_start moebius: a Moebius torus needs the harmonic m = 1 "
                             "(-pf_harmonics J -pf_dihedral 1 -pf_symmetric)")
        if kind in STARTS_3D:
            if kind == 'moebius':
                field = lambda xyz: initial.moebius_phi(xyz, geometry, eps)  # noqa: E731
            else:  # the long axis c along x
                a, c = geometry
                field = lambda xyz: initial.ellipsoid_phi(xyz, (c, a, a), eps)  # noqa: E731
            return initial.harmonic_coefficients(grid.nodes - [0.0, scene.zc], field,
                                                 scene.harmonic_set, grid.eps_min), None, False
        if kind != 'sharp':
            phi = fresh_phi(grid.nodes, kind, geometry, scene.zc, eps)
            return lifted(phi, grid.nodes, scene, perturb), None, False
        sharp = sharp_shape(scene)
        kind, geometry = check_fits(scene, eps, shape, (sharp.r, sharp.z))
        # The sharp shape's multipliers are the phase field's in the limit eps -> 0: a
        # better start for stage 1 than a least-squares fit, which takes a stomatocyte's
        # inner bud into its outer membrane (nu_A ~ 245 for 1.3 at v = 0.62, eps 0.02).
        nu = np.array([sharp.tension, sharp.pressure, 0.0][:2 if grid.symmetric else 3])
        phi = fresh_phi(grid.nodes, kind, geometry, scene.zc, eps)
        return lifted(phi, grid.nodes, scene, perturb), nu, True
    if start.attrs.get('symmetric', 0) != grid.symmetric:
        raise UsageError(
            f"the start {start.path or ''} holds a "
            f"{'half' if start.attrs.get('symmetric', 0) else 'full'}-box solution: "
            f"{'add' if start.attrs.get('symmetric', 0) else 'remove'} -pf_symmetric "
            "to continue it")
    if grid.transferred is not None and grid.transferred[0] is start:
        phi = grid.transferred[1]
    elif len(start.nodes) == grid.n_nodes and np.array_equal(start.nodes, grid.nodes):
        phi = start.phi
    else:
        phi = transfer(start.nodes, start.phi, start.locality(grid.plane),
                                  start.basis['cutoff'], grid.nodes, grid.box, grid.plane)
    phi = initial.rescaled_phi(phi, start.eps, eps)
    if phi.ndim == 1:
        return lifted(phi, grid.nodes, scene, perturb), start.nu, start.converged
    if 'harmonics_highest' in start.attrs:
        phi = widened(phi, checkpoint.harmonic_set(start.attrs, phi.shape[1]), scene,
                      start.path)
    elif phi.shape[1] != len(scene.harmonic_set):
        raise UsageError(f"the start {start.path or ''} holds {phi.shape[1]} harmonics, the "
                         f"scene {len(scene.harmonic_set)}")
    return phi, start.nu, start.converged


def widened(phi, harmonics, scene, path=''):
    """Nodal harmonics `phi` (nodes x len(harmonics)) as the scene's harmonics:
    the same columns where the sets agree, the scene's others at 0 (a start
    with fewer harmonics, as when the highest harmonic grows). Raises
    UsageError where the start holds a harmonic the scene has not."""
    have, want = harmonics.labels(), scene.harmonic_set.labels()
    if have == want:
        return phi
    missing = [label for label in have if label not in want]
    if missing:
        raise UsageError(f"the start {path} holds the harmonics {', '.join(missing)}, which "
                         f"the scene's ({', '.join(want)}) do not include")
    out = np.zeros((len(phi), len(want)))
    out[:, [want.index(label) for label in have]] = phi
    return out


def lifted(phi, nodes, scene, perturb):
    """An axisymmetric nodal phi as the harmonics of `scene` (phi itself
    without): a fresh start's harmonics m > 0 carry psi_m = r^m chi_m with
    chi_m proportional to 1 - phi^2 (on the membrane), scaled so that the
    largest psi_m at a node is `perturb` (r^m grows fast past the vesicle):
    deterministic, so that a solve does not rest on the axisymmetric
    family's saddle."""
    if not scene.harmonics:
        return phi
    h = scene.harmonic_set
    out = np.zeros((len(phi), len(h)))
    out[:, 0] = phi
    bump = np.clip(1.0 - phi * phi, 0.0, None)
    psi = nodes[:, :1] ** h.m[1:] * bump[:, None]
    out[:, 1:] = perturb * bump[:, None] / np.maximum(psi.max(axis=0), 1e-300)
    return out


def sharp_shape(scene):
    """The scene's sharp-interface shape, its curve about its centroid
    (computed once per process: `analysis.levelset.reference`)."""
    from pfmembrane.analysis.levelset import reference
    try:
        return reference(scene.branch, scene.reduced_volume, scene.c0, scene.radius, scene.k)
    except RuntimeError as e:
        raise UsageError(f"-pf_start sharp: no sharp-interface {scene.branch} "
                                    f"shape for v = {scene.reduced_volume:g}, C0 = "
                                    f"{scene.c0:g} ({e})") from None


def fresh_phi(points, kind, geometry, zc, eps):
    """phi at `points` of a fresh start of `kind` (`check_fits`)."""
    if kind == 'spheroid':
        return initial.spheroid_phi(points, *geometry, zc, eps)
    if kind == 'torus':
        return initial.profile(initial.torus_distance(points, *geometry, zc), eps)
    if kind == 'spheres':
        return initial.profile(initial.spheres_distance(points, *geometry, zc), eps)
    r, z = geometry  # the sharp curve about its centroid: placed at zc, where M = 0 holds it
    return initial.profile(initial.curve_distance(points, r, z + zc, CURVE_SPACING * eps), eps)
