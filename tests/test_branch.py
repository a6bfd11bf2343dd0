"""The continuation along a branch (`runs/branches/branch.py`, real mpiexec runs) and the
figures of existing checkpoints (`runs/figures/figures.py`)."""
import math

import h5py
import matplotlib

matplotlib.use("Agg")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

from scripts import load
from pfmembrane.io import checkpoint
from pfmembrane.kernels import nodes
from pfmembrane.analysis import sizing  # noqa: E402
from pfmembrane.kernels.initial import spheroid_axes, spheroid_phi  # noqa: E402

branch = load('runs/branches/branch.py')
figures = load('runs/figures/figures.py')

# Two volumes of the oblate branch on a small grid: a few seconds of solves each.
SMALL = ['--branch', 'oblate', '--from', '0.95', '--to', '0.9', '--step', '0.05',
         '--nodes', '700', '--box', '0.8,1.0', '--eps', '0.06']


@pytest.fixture
def run_branch(python, tmp_path_factory):
    """`python runs/branches/branch.py ARGS...`, from outside the repository."""
    def run(*args):
        return python(branch.__file__, *args, cwd=tmp_path_factory.getbasetemp())
    return run


def table_rows(path):
    """The data rows of a branch table, as lists of cells."""
    lines = path.read_text().splitlines()
    start = lines.index(next(line for line in lines if line.startswith('| v |')))
    return [[cell.strip() for cell in line.strip('|').split('|')]
            for line in lines[start + 2:] if line.startswith('|')]


@pytest.mark.slow
@pytest.mark.mpi
def test_each_volume_restarts_from_the_one_before(tmp_path, run_branch):
    out = tmp_path / 'branches'
    done = run_branch(*SMALL, '--out', out)
    assert done.returncode == 0, done.stderr
    rows = table_rows(out / 'oblate.md')
    assert [(row[0], row[1]) for row in rows] == [('0.95', 'spheroid'), ('0.9', 'v0.95.h5')]
    first, second = out / 'oblate' / 'v0.95.h5', out / 'oblate' / 'v0.9.h5'
    attrs = []
    for path in (first, second):
        with h5py.File(path, 'r') as f:
            attrs.append(dict(f.attrs))
    assert attrs[0]['parent'] == '' and attrs[1]['parent'] == str(first)
    for a, v in zip(attrs, (0.95, 0.9)):
        assert a['converged'] == 1 and a['reduced_volume'] == v and a['branch'] == 'oblate'
        assert np.isfinite(a['energy']) and np.isfinite(a['sharp_energy'])
    # Deflating raises the bending energy, as it does for the sharp-interface shapes.
    assert attrs[1]['energy'] > attrs[0]['energy']
    assert attrs[1]['sharp_energy'] > attrs[0]['sharp_energy']

    again = run_branch(*SMALL, '--out', out)
    assert again.returncode == 0, again.stderr
    assert 'mpiexec' not in again.stdout
    assert [row[-1] for row in table_rows(out / 'oblate.md')] == ['reused', 'reused']


@pytest.mark.slow
def test_a_box_too_small_for_the_branch_is_refused(tmp_path, run_branch):
    done = run_branch(*SMALL[:-4], '--box', '0.8,0.9', '--eps', '0.06', '--out', tmp_path)
    assert done.returncode == 2
    assert 'cannot hold the oblate branch' in done.stderr and 'Zb >= 0.95' in done.stderr
    assert not list(tmp_path.iterdir())


def test_volumes_and_the_default_boxes():
    assert branch.volumes(0.95, 0.65, 0.05) == [0.95, 0.9, 0.85, 0.8, 0.75, 0.7, 0.65]
    with pytest.raises(ValueError):
        branch.volumes(0.95, 0.62, 0.05)
    # The shapes grow monotonically with deflation: the ends of the branch decide the box.
    vs = [0.95, 0.65]
    # The paper's box holds the oblate branch; the prolate dumbbell at v = 0.65 (and the
    # spheroid the application checks it against) needs a taller one.
    need, _ = sizing.required_box('oblate', vs, 0.04, 0.4, margin=branch.MARGIN)
    assert branch.default_box(need) == branch.PAPER_BOX
    need, sizes = sizing.required_box('prolate', vs, 0.04, 0.4, margin=branch.MARGIN)
    rb, zb = branch.default_box(need)
    assert rb == 1.5 and math.isclose(zb, 2.2) and zb >= need[1] > 2.0
    assert 2 * (sizes['sharp'][1] + 0.12) <= zb


def small_checkpoint(path, eps=0.06, box=(0.8, 1.0), v=0.8, radius=0.4):
    """A checkpoint of the oblate spheroid's tanh profile on a small uniform grid."""
    xy = nodes.uniform(box, 400)
    area, volume = 4 * np.pi * radius ** 2, v * 4 / 3 * np.pi * radius ** 3
    a, c = spheroid_axes(area, volume, 'oblate')
    attrs = dict(energy=9.5, area=area, volume=volume, moment=0.0, eps=eps, k=1.0, c0=0.0,
                 gamma=0.8, nu_area=0.0, nu_volume=0.0, converged=1, wall_time=1.0, box=box,
                 branch='oblate', reduced_volume=v, radius=radius, cutoff=1e-6)
    checkpoint.write(path, xy, spheroid_phi(xy, a, c, 0.5 * box[1], eps), attrs)


@pytest.mark.slow
def test_figures_skip_what_is_missing(tmp_path, capsys):
    runs, out = tmp_path / 'runs', tmp_path / 'figures'
    (runs / 'adapt' / 'discocyte').mkdir(parents=True)
    small_checkpoint(runs / 'adapt' / 'discocyte' / 'O1_eps0.06.h5')
    (runs / 'branches' / 'oblate').mkdir(parents=True)
    small_checkpoint(runs / 'branches' / 'oblate' / 'v0.8.h5')
    (runs / 'dumbbell.h5').write_text('not a checkpoint')

    assert figures.main(['--runs', str(runs), '--out', str(out), '--dpi', '50']) == 0

    for name in ('discocyte/O1_eps0.06_nodes.png', 'discocyte_section.png',
                 'discocyte_spacing.png', 'discocyte_limit.png', 'shapes_3d.png',
                 'branch_oblate_3d.png'):
        assert (out / name).stat().st_size > 1000, name
    index = (out / 'index.md').read_text()
    assert '[discocyte/O1_eps0.06_nodes.png]' in index
    assert 'adapt/dumbbell' in index and 'not an HDF5 file' in index
    assert 'runs/figures/figures.py' in capsys.readouterr().err
