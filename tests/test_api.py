"""The Python API in process (one rank, COMM_SELF): solves equal command-line
runs, options stay with their solve, a grid serves many solves, results round-trip."""
import os
import subprocess
import sys
import warnings

import h5py
import numpy as np
import pytest

import pfmembrane as pf
from pfmembrane.io.options import UsageError
from pfmembrane import series as launch

pytestmark = pytest.mark.slow

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENE = pf.Scene(reduced_volume=0.8, branch='oblate')
NODES, EPS = 1500, 0.06


@pytest.fixture(scope='module')
def comm():
    PETSc = pf.api.petsc(sys.argv[:1])
    return PETSc.COMM_SELF


@pytest.fixture(scope='module')
def grid(comm):
    return pf.Grid.uniform(SCENE, nodes=NODES, comm=comm)


@pytest.fixture(scope='module')
def solved(grid):
    return pf.solve(SCENE, grid, eps=EPS)


def command_line(tmp_path, name, *args):
    """The checkpoint attributes of a one-rank command-line run."""
    out = tmp_path / f'{name}.h5'
    cmd = launch.command(1, '-options_file', 'options/discocyte.opts', '-pf_nodes', str(NODES),
                         '-pf_eps', str(EPS), '-pf_output', str(out), *args)
    launch.run(cmd, cwd=ROOT, check=False, capture_output=True)
    with h5py.File(out) as f:
        return dict(f.attrs)


def test_a_solve_equals_the_command_line_run(solved, tmp_path):
    a = command_line(tmp_path, 'cli')
    assert solved.converged and a['converged'] == 1
    assert solved.energy == pytest.approx(a['energy'], rel=1e-10)
    assert np.allclose(solved.nu, [a['nu_area'], a['nu_volume'], a['nu_moment']], rtol=1e-8)
    assert (solved.attrs['stage1_iterations'], solved.attrs['stage2_iterations']) == \
        (a['stage1_iterations'], a['stage2_iterations'])


def test_two_solves_with_their_own_options_equal_two_command_line_runs(grid, comm, tmp_path):
    PETSc = pf.api.petsc()
    before = PETSc.Options().getAll()
    loose = pf.solve(SCENE, grid, eps=EPS, options={'pf_stage1_rtol': 1e-2}, checks=False)
    capped = pf.solve(SCENE, grid, eps=EPS, options={'pf_stage1_max_it': 1}, checks=False)
    assert PETSc.Options().getAll() == before  # nothing left behind
    cli_loose = command_line(tmp_path, 'loose', '-pf_stage1_rtol', '1e-2')
    cli_capped = command_line(tmp_path, 'capped', '-pf_stage1_max_it', '1')
    assert loose.converged and not capped.converged and 'stage 1' in capped.message
    assert capped.status == 1 and cli_capped['converged'] == 0
    for ours, theirs in ((loose, cli_loose), (capped, cli_capped)):
        assert ours.energy == pytest.approx(theirs['energy'], rel=1e-10)
        assert ours.attrs['stage1_iterations'] == theirs['stage1_iterations']
    assert loose.attrs['stage1_iterations'] != capped.attrs['stage1_iterations']


def test_a_grid_serves_later_solves_without_set_up(grid, solved, tmp_path):
    again = pf.solve(SCENE, grid, eps=0.065, start=solved, checks=False)
    assert again.converged and again.attrs['time_setup'] == 0.0
    path = tmp_path / 'start.h5'
    solved.save(path)
    cold = pf.solve(SCENE, pf.Grid.of(pf.read(path)), eps=0.065, start=pf.read(path),
                    checks=False)
    assert again.energy == pytest.approx(cold.energy, rel=1e-12)
    assert cold.attrs['time_setup'] > 0.0


def test_a_result_saves_and_reads_back_with_its_paraview_file(solved, tmp_path):
    meshio = pytest.importorskip('meshio')
    path = tmp_path / 'disc.h5'
    solved.save(path)
    back = pf.read(path)
    assert back.energy == solved.energy and np.array_equal(back.phi, solved.phi)
    assert back.scene == SCENE and back.converged
    mesh = meshio.read(tmp_path / 'disc.xdmf')
    assert np.allclose(mesh.points[:, :2], solved.nodes)
    assert np.allclose(mesh.point_data['phi'], solved.phi)
    assert len(mesh.cells_dict['triangle']) == len(solved.grid.discrete.triangles)


def test_an_unused_solve_option_warns_and_is_removed(grid, solved):
    PETSc = pf.api.petsc()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        pf.solve(SCENE, grid, eps=EPS, start=solved, options={'stage2_snes_tpye': 'newtonls'},
                 checks=False)
    assert any('stage2_snes_tpye' in str(w.message) for w in caught)
    assert not any('snes_tpye' in k for k in PETSc.Options().getAll())


def test_bad_input_is_refused_with_the_option_named(grid, solved):
    with pytest.raises(UsageError, match='reduced_volume'):
        pf.Scene(reduced_volume=1.2)
    with pytest.raises(UsageError, match='pf_eps'):
        pf.solve(SCENE, grid, eps=-1.0)
    with pytest.raises(UsageError, match='below what this grid resolves'):
        pf.solve(SCENE, grid, eps=0.01)
    with pytest.raises(UsageError, match='pf_mu'):
        pf.solve(SCENE, grid, eps=EPS, options={'pf_mu': -1})
    with pytest.raises(UsageError, match='unknown option'):
        pf.solve(SCENE, grid, eps=EPS, options={'pf_eps': 0.05})  # a scene option
    with pytest.raises(UsageError, match='does not fit the grid'):
        pf.solve(pf.Scene(box=(1.6, 2.0)), grid, eps=EPS)


def test_reading_and_plotting_need_no_petsc(solved, tmp_path):
    path = tmp_path / 'disc.h5'
    solved.save(path)
    script = (
        "import sys; sys.modules['petsc4py'] = None\n"
        "import pfmembrane as pf\n"
        "from pfmembrane.analysis import plot, levelset\n"
        f"r = pf.read({str(path)!r}); print(r.energy)\n"
        f"plot.main([{str(path)!r}, '--what', 'field,3d'])\n"
        "print('petsc4py.PETSc' in sys.modules, 'matplotlib' in sys.modules)\n")
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         cwd=ROOT, env=launch.environment())
    assert out.returncode == 0, out.stderr
    lines = out.stdout.split()
    assert float(lines[0]) == solved.energy
    assert lines[-2:] == ['False', 'True']
    assert (tmp_path / 'disc_field.png').exists() and (tmp_path / 'disc_3d.png').exists()


def test_a_solve_imports_no_matplotlib(tmp_path):
    script = ("import sys, pfmembrane as pf, pfmembrane.api\n"
              "pf.api.petsc(sys.argv[:1])\n"
              "s = pf.Scene(); g = pf.Grid.uniform(s, nodes=600)\n"
              "r = pf.solve(s, g, eps=0.1, options={'pf_force': True})\n"
              "print(r.converged, 'matplotlib' in sys.modules)\n")
    out = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                         cwd=ROOT, env=launch.environment())
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1] == 'False'


def test_a_half_box_result_unfolds_into_a_full_box_start_on_a_symmetric_grid(comm):
    half = pf.Scene(reduced_volume=0.8, branch='prolate', box=(0.5, 2.0), symmetric=True)
    res = pf.solve(half, pf.Grid.uniform(half, nodes=NODES, comm=comm), eps=EPS)
    full = res.unfolded()
    assert not full.attrs['symmetric'] and res.unfolded() is not res
    assert full.unfolded() is full
    mirrored = full.nodes * [1, -1] + [0, half.box[1]]
    order = np.lexsort(full.nodes.T), np.lexsort(mirrored.T)
    assert np.array_equal(full.nodes[order[0]], mirrored[order[1]])  # no node twice
    out = pf.solve(full.scene, pf.Grid.of(full, comm=comm), EPS, start=full)
    # with a row of nodes on the plane the half box's basis and cells are the full box's
    # on the unfolded nodes: the start is the full-box solution already
    assert out.converged and out.attrs['stage2_iterations'] <= 1
    assert abs(out.energy - res.energy) < 1e-12 * res.energy
    assert np.abs(out.phi - full.phi).max() < 1e-10
    assert np.abs(out.phi[order[0]] - out.phi[order[1]]).max() < 1e-10


def test_a_floored_grid_solves_and_its_result_carries_the_floor(solved, comm, tmp_path):
    from pfmembrane.analysis import levelset
    from pfmembrane.kernels.basis import locality
    grid = pf.adapt(solved, 10.0, comm=comm, spacing_floor=0.5)
    unfloored = locality(grid.nodes, grid.params['gamma'], grid.params['spacing_smoothing'])
    assert grid.params['spacing_floor'] == 0.5
    beta = grid.discrete.beta
    assert np.mean(beta == beta.max()) >= 0.5 and np.array_equal(
        beta, np.minimum(unfloored, beta.max()))
    res = pf.solve(SCENE, grid, eps=EPS, start=solved)
    assert res.converged and res.basis['spacing_floor'] == 0.5
    res.save(tmp_path / 'floored.h5')
    back = pf.read(tmp_path / 'floored.h5', comm=comm)
    # the level set, a transfer and a regrid see the solve's basis, not the unfloored one
    assert np.array_equal(back.locality(), beta)
    assert np.array_equal(levelset.PhaseField(back.checkpoint()).beta, beta)
    assert pf.Grid.of(back, comm=comm).params == grid.params
    assert abs(res.energy / solved.energy - 1) < 0.01
