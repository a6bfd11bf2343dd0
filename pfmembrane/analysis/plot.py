"""Figures of pfmembrane checkpoints.

Command line::

    python -m pfmembrane.analysis.plot CHECKPOINT.h5 [more.h5 ...] [-o OUTDIR]
        [--what field,nodes,section,3d,spacing] [--z-mid Z] [--dpi DPI]

writes ``<stem>_<what>.png`` for every checkpoint and figure (the
``section`` figure gathers all checkpoints and is named after the first one)
into OUTDIR, by default the checkpoint's directory, and prints each path.

The figures show the max-ent approximant phi_h (`pfmembrane.analysis.levelset.PhaseField`),
not the nodal coefficients, which it does not interpolate: on a graded grid
they oscillate far outside [-1, 1] (-3.6 ... 6.1 on the dumbbell's P14 at
eps 0.01, where phi_h stays within 1e-3 of it) and cross zero away from the
membrane. Colour maps interpolate phi_h at the nodes linearly on their
Delaunay triangulation; sections evaluate phi_h on the line; the membrane is
the level set phi_h = 0 (`pfmembrane.analysis.levelset.level_set`). A
checkpoint with azimuthal harmonics is drawn in 3D only (its triangulated
phi_h = 0, `pfmembrane.analysis.field3d.level_surface`) and by its spacing.
"""

import argparse
import os
import sys

import matplotlib
import matplotlib.pyplot as plt
import matplotlib.tri as mtri
import numpy as np

from pfmembrane.io import checkpoint
from pfmembrane.analysis import field3d, levelset
from pfmembrane.kernels.nodes import nodal_spacing

__all__ = ["FIGURES", "readable", "triangulation",
           "plot_field", "plot_section", "plot_3d", "plot_spacing", "main"]

FIGURES = ("field", "nodes", "section", "3d", "spacing")


def readable(paths, unfold=True):
    """The checkpoints of `paths` that can be read, and why the others cannot.

    Not collective.  For scripts that draw what exists and skip the rest
    with a note.

    Parameters
    ----------
    paths : iterable of str
    unfold : bool
        Unfold a half-box checkpoint to the full box (what the figures show).

    Returns
    -------
    (dict, dict)
        {path: Checkpoint} of the readable ones, in the order of `paths`, and
        {path: message} of the others (`CheckpointError`: missing, not HDF5,
        truncated, of another schema ...).
    """
    found, errors = {}, {}
    for path in paths:
        try:
            ckpt = checkpoint.read(path)
        except checkpoint.CheckpointError as exc:
            errors[path] = str(exc)
            continue
        found[path] = ckpt.unfolded() if unfold else ckpt
    return found, errors


def triangulation(ckpt):
    """Delaunay triangulation of the nodes in the (r, z) half-plane.

    Not collective.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint

    Returns
    -------
    matplotlib.tri.Triangulation
    """
    return mtri.Triangulation(ckpt.nodes[:, 0], ckpt.nodes[:, 1])


def plot_field(ckpt, ax=None, nodes=True):
    """Draw phi_h over the full cross section with the membrane phi_h = 0.

    Not collective.  The computed half-plane r >= 0 is mirrored to r < 0.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint
    ax : matplotlib.axes.Axes, optional
        Axes to draw into; a new figure by default.
    nodes : bool
        Also draw the nodes as small dots, on the mirrored half only so that
        the field stays readable on the other.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        _, ax = plt.subplots()
    field = levelset.PhaseField(ckpt)
    phi = field(ckpt.nodes)
    half = triangulation(ckpt)
    mirror = mtri.Triangulation(-half.x, half.y, half.triangles)
    for tri in (half, mirror):
        image = ax.tripcolor(tri, phi, shading="gouraud", cmap="RdBu_r",
                             vmin=-1.0, vmax=1.0)
    for line in levelset.membrane(ckpt, field=field):
        for sign in (1.0, -1.0):
            ax.plot(sign * line[:, 0], line[:, 1], color="k", linewidth=1.2,
                    label="_membrane")
    if nodes:
        ax.plot(-ckpt.nodes[:, 0], ckpt.nodes[:, 1], ".", color="k",
                markersize=1.5)
    ax.figure.colorbar(image, ax=ax, label=r"$\phi$")
    rb, zb = ckpt.box
    ax.set_xlim(-rb, rb)
    ax.set_ylim(0.0, zb)
    ax.set_aspect("equal")
    ax.set_xlabel("r")
    ax.set_ylabel("z")
    ax.set_title(_summary(ckpt))
    return ax


def plot_section(ckpts, ax=None, z_mid=None, samples=400):
    """Draw phi_h along the horizontal line z = z_mid for several checkpoints.

    Not collective.

    Parameters
    ----------
    ckpts : sequence of pfmembrane.io.checkpoint.Checkpoint
        Checkpoints to compare, e.g. for several eps.
    ax : matplotlib.axes.Axes, optional
        Axes to draw into; a new figure by default.
    z_mid : float, optional
        Height of the section; by default the centre of each box.
    samples : int
        Number of points along r in [0, Rb].

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        _, ax = plt.subplots()
    for ckpt in ckpts:
        rb, zb = ckpt.box
        z = 0.5 * zb if z_mid is None else z_mid
        r = np.linspace(0.0, rb, samples)
        phi = levelset.PhaseField(ckpt)(np.column_stack([r, np.full_like(r, z)]))
        ax.plot(r, phi, label=f"eps = {ckpt.attrs['eps']:g}")
    ax.axhline(0.0, color="k", linewidth=0.5)
    ax.set_xlabel("r")
    ax.set_ylabel(r"$\phi$")
    ax.set_title("z = Zb / 2" if z_mid is None else f"z = {z_mid:g}")
    ax.legend()
    return ax


def plot_3d(ckpt, ax=None, n_theta=48, curve=None):
    """Draw the membrane: the surface of revolution of phi_h = 0 about the
    z axis, or with harmonics the triangulated 3D surface phi_h = 0
    (`field3d.level_surface`).

    Not collective.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D, optional
        3D axes to draw into; a new figure by default.
    n_theta : int
        Number of meridians.
    curve : list of ndarray, optional
        The membrane (`pfmembrane.analysis.levelset.membrane`), if the caller has it.

    Returns
    -------
    mpl_toolkits.mplot3d.axes3d.Axes3D
    """
    if ax is None:
        ax = plt.figure().add_subplot(projection="3d")
    if np.ndim(ckpt.phi) == 2:
        surf = field3d.level_surface(ckpt)
        if len(surf.triangles):
            x, y, z = surf.vertices.T
            ax.plot_trisurf(x, y, z, triangles=surf.triangles, color="tab:orange",
                            linewidth=0)
    else:
        theta = np.linspace(0.0, 2.0 * np.pi, n_theta)
        for line in levelset.membrane(ckpt) if curve is None else curve:
            r, z = line[:, :1], line[:, 1:]
            ax.plot_surface(r * np.cos(theta), r * np.sin(theta),
                            np.broadcast_to(z, (len(z), n_theta)),
                            color="tab:orange", linewidth=0)
    rb, zb = ckpt.box
    ax.set_xlim(-rb, rb)
    ax.set_ylim(-rb, rb)
    ax.set_zlim(0.0, zb)
    ax.set_box_aspect((2.0 * rb, 2.0 * rb, zb))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")
    ax.set_title(_summary(ckpt))
    return ax


def plot_spacing(ckpt, ax=None, bins=40):
    """Histogram of the nodal spacing relative to a uniform grid.

    Not collective.  The reference sqrt(Rb Zb / N) is the spacing of a
    uniform square grid with the same number of nodes in the same box, so
    negative values mark refined nodes.

    Parameters
    ----------
    ckpt : pfmembrane.io.checkpoint.Checkpoint
    ax : matplotlib.axes.Axes, optional
        Axes to draw into; a new figure by default.
    bins : int
        Number of histogram bins.

    Returns
    -------
    matplotlib.axes.Axes
    """
    if ax is None:
        _, ax = plt.subplots()
    rb, zb = ckpt.box
    uniform = np.sqrt(rb * zb / len(ckpt.nodes))
    ax.hist(nodal_spacing(ckpt.nodes) - uniform, bins=bins)
    ax.axvline(0.0, color="k", linewidth=0.5)
    ax.set_xlabel(r"$h_a - h_{uniform}$")
    ax.set_ylabel("nodes")
    ax.set_title(f"N = {len(ckpt.nodes)}, h_uniform = {uniform:.3g}")
    return ax


def main(argv=None):
    """Write the requested figures of the given checkpoints as PNG files.

    Not collective.

    Parameters
    ----------
    argv : list of str, optional
        Command line arguments; ``sys.argv[1:]`` by default.

    Returns
    -------
    int
        Exit status: 0 on success, 1 if a checkpoint cannot be read.
    """
    args = _parser().parse_args(argv)
    matplotlib.use("Agg")
    try:
        ckpts = [checkpoint.read(path).unfolded() for path in args.checkpoints]
    except checkpoint.CheckpointError as exc:
        print(f"pfmembrane.analysis.plot: error: {exc}", file=sys.stderr)
        return 1
    draw = {
        "field": lambda ckpt: plot_field(ckpt, nodes=False),
        "nodes": lambda ckpt: plot_field(ckpt, nodes=True),
        "3d": plot_3d,
        "spacing": plot_spacing,
    }
    for what in args.what:
        # phi_h(r, z) alone is a section of an axisymmetric field only
        meridian = [(path, ckpt) for path, ckpt in zip(args.checkpoints, ckpts)
                    if np.ndim(ckpt.phi) == 1 or what in ("3d", "spacing")]
        drawn = {path for path, _ in meridian}
        for path in args.checkpoints:
            if path not in drawn:
                print(f"pfmembrane.analysis.plot: {path} has harmonics: no '{what}' figure "
                      "(the '3d' one draws its phi_h = 0)", file=sys.stderr)
        if what == "section" and meridian:
            ax = plot_section([ckpt for _, ckpt in meridian], z_mid=args.z_mid)
            _save(ax.figure, meridian[0][0], what, args)
            continue
        for path, ckpt in meridian:
            _save(draw[what](ckpt).figure, path, what, args)
    return 0


def _parser():
    parser = argparse.ArgumentParser(
        prog="python -m pfmembrane.analysis.plot",
        description="Plot pfmembrane checkpoints as PNG files.")
    parser.add_argument("checkpoints", nargs="+", metavar="CHECKPOINT.h5")
    parser.add_argument("-o", "--outdir",
                        help="output directory (default: beside each "
                             "checkpoint)")
    parser.add_argument("--what", type=_figure_list, default=list(FIGURES),
                        help="comma-separated figures among "
                             f"{','.join(FIGURES)} (default: all)")
    parser.add_argument("--z-mid", type=float,
                        help="height of the section (default: box centre)")
    parser.add_argument("--dpi", type=float, default=150.0,
                        help="resolution of the PNG files (default: 150)")
    return parser


def _figure_list(text):
    names = [name.strip() for name in text.split(",") if name.strip()]
    unknown = sorted(set(names) - set(FIGURES))
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f"unknown figure {', '.join(unknown) or repr(text)}; choose among "
            f"{','.join(FIGURES)}")
    return names


def _summary(ckpt):
    return (f"eps = {ckpt.attrs['eps']:g}, E = {ckpt.attrs['energy']:.6g}"
            + ("" if ckpt.attrs["converged"] else " (not converged)"))


def _save(figure, ckpt_path, what, args):
    outdir = args.outdir or os.path.dirname(os.path.abspath(ckpt_path))
    os.makedirs(outdir, exist_ok=True)
    stem = os.path.splitext(os.path.basename(ckpt_path))[0]
    out = os.path.join(outdir, f"{stem}_{what}.png")
    figure.savefig(out, dpi=args.dpi, bbox_inches="tight")
    # Closing releases pyplot's reference, which would keep every figure of
    # a long list of checkpoints alive.
    plt.close(figure)
    print(out)


if __name__ == "__main__":
    sys.exit(main())
