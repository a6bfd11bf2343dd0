"""The figures of the README, regenerated from existing checkpoints.

    python runs/figures/figures.py [--runs runs] [--out runs/figures] [--dpi 150]

For the discocyte and the dumbbell it reads the checkpoints of the adaptive sequence,
RUNS/adapt/<shape>/<grid>_eps<eps>.h5, and the single run RUNS/<shape>.h5, those that exist,
and draws with `pfmembrane.analysis.plot` and `pfmembrane.analysis.levelset`:

- the phase field with the nodes of every checkpoint (Figures 7, 10);
- phi along the cutline z = Zb / 2 for the smallest eps of every grid of the sequence, with a
  zoom on the interface and the sharp-interface step (Figure 8c-e);
- the nodal spacing histograms of the grids of the sequence (Figure B.11);
- the zero level sets of the same checkpoints against the sharp interface (Figure 8b, by
  `python -m pfmembrane.analysis.levelset`, which also writes its table);
- the discocyte and the dumbbell revolved about the axis (Figure 5), and the shapes of the
  branches under RUNS/branches (Figure 6, `python runs/branches/branch.py`).

A missing or unreadable checkpoint is skipped with a note, never an error. OUT/index.md lists
the figures, the checkpoints each one shows, and the notes. Runs from any working directory:
RUNS and OUT default to the repository's runs/ and runs/figures/, and paths inside the
repository are shown relative to its root.
"""
import argparse
import contextlib
import glob
import io
import os
import sys

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.path import Path

from pfmembrane import report
from pfmembrane.analysis import levelset, plot
from pfmembrane.paper import grid_name

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
BRANCHES = ('oblate', 'prolate')   # the branches of RUNS/branches (runs/branches/branch.py)
# Shape name and the paper's figure of its adapted grids.
SHAPES = (('discocyte', '7'), ('dumbbell', '10'))
ZOOM = 5.0      # half-width of the zoomed section, in units of the largest eps shown


class Index:
    """The figures written and the notes on what was skipped, for OUT/index.md."""

    def __init__(self, out, record):
        self.out = out
        self.record = record   # report.provenance() at the start
        self.rows = []
        self.notes = []

    def save(self, figure, name, paper, sources, dpi):
        """Write `figure` as OUT/`name` and list it with the checkpoints it shows."""
        path = os.path.join(self.out, name)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        figure.savefig(path, dpi=dpi, bbox_inches='tight')
        # Closing releases pyplot's reference to the figure.
        plt.close(figure)
        self.add(name, paper, sources)
        print(path)

    def add(self, name, paper, sources):
        """List OUT/`name`, a file already written, with the checkpoints it shows."""
        self.rows.append((name, paper, ', '.join(f"`{s}`" for s in sources)))

    def note(self, text):
        """Record what was skipped and why; also reported on stderr."""
        self.notes.append(text)
        print(f"runs/figures/figures.py: {text}", file=sys.stderr)

    def write(self, runs):
        """Write OUT/index.md; returns its path."""
        lines = [*report.header('Figures', self.record),
                 f"Regenerated from the checkpoints under `{runs}` by `python runs/figures/figures.py "
                 f"--runs {runs} --out {self.out}` (`make figures`).", '',
                 '| figure | paper | checkpoints |', '|---|---|---|']
        lines += [f"| [{name}]({name}) | {paper} | {sources} |" for name, paper, sources in self.rows]
        if not self.rows:
            lines.append('| (none: no checkpoints found) | | |')
        if self.notes:
            lines += ['', '## Notes', ''] + [f"- {n}" for n in self.notes]
        path = os.path.join(self.out, 'index.md')
        os.makedirs(self.out, exist_ok=True)
        print(report.write(path, lines))
        return path


def load(paths, index):
    """{path: Checkpoint} of the readable `paths`, unfolded to the full box; the
    others are noted."""
    found, errors = plot.readable(paths)
    for message in errors.values():
        index.note(message)
    return found


def branch_checkpoints(directory, index):
    """The readable checkpoints of every branch under `directory` (`<branch>/v*.h5`,
    as runs/branches/branch.py writes them): {branch: [(path, Checkpoint)]} in order
    of v; the unreadable ones are noted."""
    found = {}
    for branch in BRANCHES:
        ckpts, errors = plot.readable(glob.glob(os.path.join(directory, branch, 'v*.h5')),
                                      unfold=False)
        for message in errors.values():
            index.note(message)
        if ckpts:
            found[branch] = sorted(ckpts.items(), key=lambda pair: pair[1].attrs['reduced_volume'])
    return found


def sequence_order(ckpts):
    """The paths of a sequence in the order of its steps: by grid (O1, O11, O12, ...)
    and, on one grid, by decreasing eps."""
    return sorted(ckpts, key=lambda p: (grid_name(p), -ckpts[p].attrs['eps']))


def finest_per_grid(ckpts, index):
    """The converged checkpoint of smallest eps on every grid of a sequence:
    the solutions of Figure 7 (bottom)."""
    best = {}
    for path in sequence_order(ckpts):
        if ckpts[path].attrs['converged']:
            best[grid_name(path)] = path
        else:
            index.note(f"`{path}` did not converge (converged = 0): not in the section or "
                       "limit figures")
    return list(best.values())


def field_figures(shape, ckpts, number, index, dpi):
    """The phase field and the nodes of every (path, checkpoint) of `ckpts`
    (Figures 7, 10)."""
    for path, ckpt in ckpts:
        ax = plot.plot_field(ckpt, nodes=True)
        ax.set_title(f"{grid_name(path)}: {ax.get_title()}")
        stem = os.path.splitext(os.path.basename(path))[0]
        index.save(ax.figure, os.path.join(shape, f"{stem}_nodes.png"), number, [path], dpi)


def section_figure(shape, paths, ckpts, index, dpi):
    """phi along z = Zb / 2 for several eps, whole and zoomed on the interface,
    with the sharp-interface step (Figure 8c-e)."""
    chosen = [ckpts[p] for p in paths]
    figure, (whole, zoom) = plt.subplots(1, 2, figsize=(11.0, 4.2))
    step = _sharp_step(chosen[0])
    for ax in (whole, zoom):
        plot.plot_section(chosen, ax=ax)
        for line, path in zip(ax.get_lines(), paths):
            line.set_label(f"{grid_name(path)}, {line.get_label()}")
        if step is not None:
            ax.plot(*step, color='k', linewidth=1.0, linestyle='--', label='sharp interface')
        ax.legend(fontsize='small')
    if step is not None:
        width = ZOOM * max(c.attrs['eps'] for c in chosen)
        crossings = step[0][np.flatnonzero(np.diff(step[1]))]
        zoom.set_xlim(crossings[-1] - width, crossings[-1] + width)
    zoom.set_title(f"{zoom.get_title()}, at the interface")
    index.save(figure, f"{shape}_section.png", '8c-e', paths, dpi)


def _sharp_step(ckpt, samples=2000):
    """(r, phi) of the sharp-interface shape of the checkpoint's scene along
    z = Zb / 2: +1 inside, -1 outside; None without a sharp counterpart."""
    try:
        shape = levelset.reference(*(ckpt.attrs[key] for key in
                                  ('branch', 'reduced_volume', 'c0', 'radius', 'k')))
    except (KeyError, ValueError, RuntimeError):
        return None
    # The curve, closed along the axis, bounds the vesicle; its centroid sits at Zb / 2.
    r = np.linspace(0.0, ckpt.box[0], samples)[1:]
    inside = Path(np.column_stack([shape.r, shape.z])).contains_points(
        np.column_stack([r, np.zeros_like(r)]))
    if not inside.any():
        return None
    return r, np.where(inside, 1.0, -1.0)


def spacing_figure(shape, ckpts, index, dpi):
    """Histograms of the nodal spacing, one per grid of the sequence (Figure B.11)."""
    first = {}
    for path in sequence_order(ckpts):
        first.setdefault(grid_name(path), path)
    ncols = min(2, len(first))
    nrows = -(-len(first) // ncols)
    figure, axes = plt.subplots(nrows, ncols, figsize=(5.0 * ncols, 3.6 * nrows), squeeze=False)
    for ax, (grid, path) in zip(axes.flat, first.items()):
        plot.plot_spacing(ckpts[path], ax=ax)
        ax.set_title(f"{grid}: {ax.get_title()}")
    for ax in axes.flat[len(first):]:
        ax.set_visible(False)
    figure.tight_layout()
    index.save(figure, f"{shape}_spacing.png", 'B.11', list(first.values()), dpi)


def limit_figure(shape, paths, index):
    """Figure 8b and its table, by the command line of `pfmembrane.analysis.levelset`."""
    out = os.path.join(index.out, f"{shape}_limit")
    errors = io.StringIO()
    with contextlib.redirect_stderr(errors):
        status = levelset.main([*paths, '--out', out])
    if status != 0:
        index.note(f"no sharp-interface figure for the {shape}: {errors.getvalue().strip()}")
        return
    index.add(f"{shape}_limit.png", '8b', paths)
    index.add(f"{shape}_limit.md", '8b (table)', paths)


def revolved(figure, ckpts):
    """One 3D axes per checkpoint, in a row of `figure`, with its membrane revolved
    (`pfmembrane.analysis.plot.plot_3d`), all framed at one scale on the membranes: plot_3d
    shows the whole box, where a vesicle is small. Returns the axes."""
    curves = [levelset.membrane(c) for c in ckpts]
    axes = [plot.plot_3d(c, ax=figure.add_subplot(1, len(ckpts), i, projection='3d'), curve=curve)
            for i, (c, curve) in enumerate(zip(ckpts, curves), start=1)]
    outlines = [np.vstack(curve) - [0.0, 0.5 * c.box[1]] for c, curve in zip(ckpts, curves) if curve]
    if outlines:
        r, z = 1.05 * np.max(np.abs(np.vstack(outlines)), axis=0)
        for ax, ckpt in zip(axes, ckpts):
            centre = 0.5 * ckpt.box[1]
            ax.set_xlim(-r, r)
            ax.set_ylim(-r, r)
            ax.set_zlim(centre - z, centre + z)
            ax.set_box_aspect((2.0 * r, 2.0 * r, 2.0 * z))
    return axes


def shapes_figure(chosen, index, dpi):
    """The discocyte and the dumbbell revolved about the axis (Figure 5)."""
    figure = plt.figure(figsize=(5.0 * len(chosen), 5.0))
    for ax, (shape, _, _) in zip(revolved(figure, [ckpt for _, _, ckpt in chosen]), chosen):
        ax.set_title(f"{shape}: {ax.get_title()}")
    index.save(figure, 'shapes_3d.png', '5', [path for _, path, _ in chosen], dpi)


def branch_figures(directory, index, dpi):
    """The shapes along each branch revolved about the axis (Figure 6)."""
    found = branch_checkpoints(directory, index)
    if not found:
        index.note(f"no branch checkpoints under `{directory}` (`make branches`)")
    for branch, pairs in found.items():
        for path, ckpt in pairs:
            if not ckpt.attrs['converged']:
                index.note(f"`{path}` did not converge (converged = 0): not in the {branch} "
                           "branch figure")
        # In the order of the continuation: deflating.
        pairs = [(path, ckpt) for path, ckpt in pairs[::-1] if ckpt.attrs['converged']]
        if not pairs:
            continue
        figure = plt.figure(figsize=(2.6 * len(pairs), 3.2))
        for ax, (_, ckpt) in zip(revolved(figure, [ckpt for _, ckpt in pairs]), pairs):
            ax.set_title(f"v = {ckpt.attrs['reduced_volume']:g}, E = {ckpt.attrs['energy']:.4g}",
                         fontsize='small')
            ax.set_axis_off()
        index.save(figure, f"branch_{branch}_3d.png", '6', [path for path, _ in pairs], dpi)
    energy = os.path.join(directory, 'energy.png')
    if os.path.exists(energy):
        index.add(os.path.relpath(energy, index.out), '6 (energies)', sources=[directory])


def from_root(path):
    """`path` (from the working directory) relative to the repository's root when it is
    inside it, else absolute: what the page shows, valid from the root."""
    path = os.path.abspath(path)
    rel = os.path.relpath(path, ROOT)
    return path if rel.startswith(os.pardir) else rel


def main(argv=None):
    """Write every figure the existing checkpoints allow; returns 0."""
    ap = argparse.ArgumentParser(prog='python runs/figures/figures.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--runs', default=os.path.join(ROOT, 'runs'),
                    help="directory of the runs (default: the repository's runs)")
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'figures'))
    ap.add_argument('--dpi', type=float, default=150.0)
    args = ap.parse_args(argv)
    runs, out = from_root(args.runs), from_root(args.out)
    with contextlib.chdir(ROOT):
        return draw(runs, out, args.dpi)


def draw(runs, out, dpi):
    """The figures of the checkpoints under `runs` into `out`, and out/index.md."""
    matplotlib.use('Agg')
    index = Index(out, report.provenance())
    chosen = []
    for shape, number in SHAPES:
        pattern = os.path.join(runs, 'adapt', shape, '*.h5')
        sequence = load(sorted(glob.glob(pattern)), index)
        single = os.path.join(runs, f"{shape}.h5")
        alone = load([single], index) if os.path.exists(single) else {}
        if not sequence:
            index.note(f"no checkpoints match `{pattern}` (`make adapt-{shape}`): no figures "
                       f"of the adaptive {shape} sequence")
        if not alone:
            index.note(f"no `{single}`")
        field_figures(shape, [(p, sequence[p]) for p in sequence_order(sequence)]
                      + list(alone.items()), number, index, dpi)
        finest = finest_per_grid(sequence, index)
        if sequence:
            spacing_figure(shape, sequence, index, dpi)
        if finest:
            section_figure(shape, finest, sequence, index, dpi)
            limit_figure(shape, finest, index)
        # Figure 5 shows the single run, else the finest converged solution of the sequence.
        if alone or finest:
            pick = next(iter(alone), None) or finest[-1]
            chosen.append((shape, pick, {**sequence, **alone}[pick]))
    if chosen:
        shapes_figure(chosen, index, dpi)
    branch_figures(os.path.join(runs, 'branches'), index, dpi)
    index.write(runs)
    return 0


if __name__ == '__main__':
    sys.exit(main())
