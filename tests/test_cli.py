"""The command line: help, bad input, unused options, 1 vs 2 ranks, restart, restart after
SIGTERM (real mpiexec runs)."""
import os
import signal
import subprocess
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
import pytest

from pfmembrane.io import checkpoint

pytestmark = pytest.mark.slow

SMALL = ['-pf_nodes', '1000', '-pf_box', '0.8,1.0', '-pf_eps', '0.06']


def test_help_lists_the_application_options(pfm):
    out = pfm('-help', n=1)
    assert out.returncode == 0
    for name in ('eps', 'k', 'c0', 'radius', 'reduced_volume', 'box', 'branch', 'nodes',
                 'gamma', 'restart', 'adapt', 'output', 'cutoff'):
        assert f'-pf_{name}' in out.stdout


BASE = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '1500']
# Each case: arguments ({tmp}: the directory of bad_files) and the message it must give.
BAD_INPUT = {
    'eps<0': ([*BASE, '-pf_eps', '-0.01'], 'pf_eps must be > 0'),
    'eps=0': ([*BASE, '-pf_eps', '0'], '-pf_eps must be > 0'),
    'eps-text': ([*BASE, '-pf_eps', 'abc'], "cannot read 'abc'"),
    'v>1': ([*BASE, '-pf_reduced_volume', '1.2'], 'reduced_volume must lie in (0, 1]'),
    'v-nan': ([*BASE, '-pf_reduced_volume', 'nan'], 'finite'),
    'branch': ([*BASE, '-pf_branch', 'cylinder'], "unknown shape 'cylinder'"),
    'box': ([*BASE, '-pf_box', '0.5,0.6'], 'cannot hold the oblate vesicle'),
    'nodes': ([*BASE, '-pf_nodes', '50'], 'too few'),
    'band': ([*BASE, '-pf_adapt_band', '0.1'], '-pf_adapt_band needs -pf_adapt'),
    'partition': ([*BASE, '-pf_partition', 'metis'], '-pf_partition must be one of bisection'),
    'unresolved': ([*BASE, '-pf_eps', '0.03'], 'below what this grid resolves'),
    'typo': ([*BASE, '-pf_epss', '0.03'], "unknown option '-pf_epss' (did you mean -pf_eps?)"),
    'typo-in-file': (['-options_file', '{tmp}/typo.opts'],
                     "unknown option '-pf_nodez' (did you mean -pf_nodes?)"),
    'no-options-file': (['-options_file', '{tmp}/absent.opts'], 'Unable to open options file'),
    'bad-options-file': (['-options_file', '{tmp}/malformed.opts'],
                         'Unknown first token in options file'),
    'restart-absent': ([*BASE, '-pf_restart', '/nonexistent/x.h5'], 'no such file'),
    'restart-text': ([*BASE, '-pf_restart', '{tmp}/text.h5'], 'not an HDF5 file'),
    'restart-truncated': ([*BASE, '-pf_restart', '{tmp}/truncated.h5'],
                          'truncated or corrupt HDF5 file'),
    'restart-version': ([*BASE, '-pf_restart', '{tmp}/version.h5'], 'wrong version 2'),
    'restart-box': ([*BASE, '-pf_restart', '{tmp}/box.h5'], 'differs from the expected'),
    'restart-half': ([*BASE, '-pf_restart', '{tmp}/half.h5'],
                     'holds a half-box solution: add -pf_symmetric'),
    'output-dir': ([*BASE, '-pf_output', '{tmp}'], 'is a directory'),
    'output-below-file': ([*BASE, '-pf_output', '{tmp}/text.h5/x.h5'], 'is not a directory'),
}


def bad_files(tmp):
    """Options files and restart checkpoints that must be refused."""
    (tmp / 'typo.opts').write_text('-pf_eps 0.06\n-pf_nodez 1500\n')
    (tmp / 'malformed.opts').write_text('pf_eps 0.06\n')
    (tmp / 'text.h5').write_text('not a checkpoint\n')
    nodes = np.random.default_rng(0).uniform((0.0, 0.0), (1.5, 2.0), (300, 2))
    attrs = {key: 1.0 for key in checkpoint.FLOAT_ATTRS}
    attrs.update(converged=0, box=(1.5, 2.0))
    for name, change in (('truncated', {}), ('version', {'version': 2}),
                         ('box', {'box': (1.0, 2.0)}), ('half', {'symmetric': 1})):
        path = tmp / f'{name}.h5'
        checkpoint.write(path, nodes, np.zeros(300), attrs)
        with h5py.File(path, 'r+') as f:
            f.attrs.update(change)
    os.truncate(tmp / 'truncated.h5', os.path.getsize(tmp / 'truncated.h5') // 2)


@pytest.fixture(scope='module')
def bad_runs(tmp_path_factory, pfm):
    """Every BAD_INPUT case, eight at a time: a run that exits with an error spends
    most of its time idle, in Open MPI's shutdown of the job."""
    tmp = tmp_path_factory.mktemp('bad')
    bad_files(tmp)

    def attempt(args):
        try:
            return pfm(*(a.format(tmp=tmp) for a in args), timeout=120)
        except subprocess.TimeoutExpired as e:
            return e

    with ThreadPoolExecutor(8) as pool:
        runs = {case: pool.submit(attempt, args) for case, (args, _) in BAD_INPUT.items()}
        return {case: run.result() for case, run in runs.items()}


@pytest.mark.mpi
@pytest.mark.parametrize('case', BAD_INPUT)
def test_bad_input_is_one_line_and_nonzero_on_every_rank(bad_runs, case):
    out, message = bad_runs[case], BAD_INPUT[case][1]
    assert not isinstance(out, subprocess.TimeoutExpired), f'{case} hung'
    assert out.returncode == 2, out.stderr
    errors = [line for line in out.stderr.splitlines() if line.startswith('pfmembrane')]
    assert len(errors) == 1 and message in errors[0], out.stderr
    assert 'Traceback' not in out.stderr
    if case != 'unresolved':
        assert 'grid:' not in out.stdout  # refused before the expensive work


def _energy(path):
    with h5py.File(path, 'r') as f:
        return dict(f.attrs), f['phi'][:]


@pytest.fixture(scope='module')
def runs(tmp_path_factory, pfm):
    d = tmp_path_factory.mktemp('cli')
    res = {}
    for n in (1, 2, 3):  # 3 ranks oversubscribe the 2 cores: a partition that is not a power of 2
        path = str(d / f'disc{n}.h5')
        out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_output', path, n=n)
        assert out.returncode == 0, out.stderr
        res[n] = path
    return d, res


@pytest.mark.mpi
def test_one_two_and_three_ranks_agree(runs):
    _, res = runs
    a1, phi1 = _energy(res[1])
    for n in (2, 3):
        a, phi = _energy(res[n])
        assert a1['converged'] == 1 and a['converged'] == 1
        assert a['n_procs'] == n
        assert abs(a1['energy'] / a['energy'] - 1) < 1e-8
        assert np.max(np.abs(phi1 - phi)) < 1e-6
    a2 = _energy(res[2])[0]
    for key in ('energy', 'area', 'volume', 'moment', 'eps', 'k', 'c0', 'gamma', 'nu_area',
                'nu_volume', 'converged', 'wall_time', 'n_procs'):
        assert key in a2
    # Constraints met to 1e-8 relative at the end of stage 2; tension > 0, pressure < 0.
    R = 0.4
    assert abs(a2['area'] / (4 * np.pi * R ** 2) - 1) < 1e-8
    assert abs(a2['volume'] / (0.8 * 4 / 3 * np.pi * R ** 3) - 1) < 1e-8
    assert a2['nu_area'] > 0 and a2['nu_volume'] < 0


@pytest.mark.mpi
def test_restart_reaches_the_same_answer(runs, pfm):
    d, res = runs
    path = str(d / 'restarted.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_restart', res[2],
              '-pf_output', path)
    assert out.returncode == 0, out.stderr
    a, _ = _energy(path)
    assert abs(a['energy'] / _energy(res[2])[0]['energy'] - 1) < 1e-8
    assert a['stage1_iterations'] <= 3  # it starts at the answer


@pytest.mark.mpi
def test_adapted_restart_at_a_smaller_eps(runs, pfm):
    # CVT relocation of the restart's nodes, its phi transferred and narrowed to the new eps.
    d, res = runs
    path = str(d / 'adapted.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_restart', res[2],
              '-pf_adapt', '10', '-pf_adapt_band', '0.1', '-pf_eps', '0.05', '-pf_output', path)
    assert out.returncode == 0, out.stderr
    assert 'adapt: CVT f=10 band=0.1' in out.stdout
    a, _ = _energy(path)
    start = _energy(res[2])[0]
    assert a['converged'] == 1 and a['eps'] == 0.05
    assert (a['adapt'], a['adapt_band']) == (10.0, 0.1) and a['n_nodes'] == start['n_nodes']
    assert 0.0 < a['time_adapt'] < a['time_setup']
    assert a['energy'] < start['energy']  # a thinner interface, the sharp limit below


@pytest.mark.mpi
def test_a_restart_at_a_smaller_eps_keeps_its_multipliers(tmp_path, pfm):
    # The solved multipliers start stage 1 and its first pass converges before the
    # update: one outer iteration, the multipliers already at the answer's. The
    # least-squares start took two, through nu_A 34 (answer 11.6).
    grid = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '2500']
    start, path = str(tmp_path / 'start.h5'), str(tmp_path / 'eps0.06.h5')
    assert pfm(*grid, '-pf_eps', '0.075', '-pf_start', 'sharp', '-pf_output', start).returncode == 0
    out = pfm(*grid, '-pf_eps', '0.06', '-pf_restart', start, '-pf_monitor',
              '-pf_output', path)
    assert out.returncode == 0, out.stderr
    assert 'stage1: 1 its' in out.stdout
    row = [line.split() for line in out.stdout.splitlines() if line.startswith('  AL')][0]
    a, _ = _energy(path)
    assert a['converged'] == 1
    assert abs(float(row[row.index('nuA') + 1]) / a['nu_area'] - 1) < 1e-3
    assert abs(float(row[row.index('nuV') + 1]) / a['nu_volume'] - 1) < 1e-3


def test_a_failed_stage_2_keeps_the_better_of_its_start_and_end(tmp_path, pfm):
    # Steps of three times Newton's from a coarse stage 1 raise |F|: the checkpoint
    # holds the stage-1 state, not the last step.
    path = str(tmp_path / 'failed.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_stage1_rtol', '0.5',
              '-stage2_snes_max_it', '1', '-stage2_snes_linesearch_damping', '3',
              '-stage2_snes_monitor', '-pf_output', path, n=1)
    assert out.returncode == 1
    norms = [float(line.split()[-1]) for line in out.stdout.splitlines() if 'SNES Function' in line]
    assert len(norms) == 2 and norms[1] > norms[0]
    stage1 = float(out.stdout.split('stage1:')[1].split(' E ')[1].split(',')[0])
    a, _ = _energy(path)
    assert a['converged'] == 0
    assert abs(a['energy'] - stage1) < 1e-7


@pytest.mark.mpi
def test_sigterm_on_one_rank_checkpoints_and_the_restart_reaches_the_same_energy(runs, tmp_path,
                                                                                 pfm, mpirun):
    _, res = runs
    stopped = str(tmp_path / 'stopped.h5')
    run = mpirun(['-options_file', 'options/discocyte.opts', *SMALL, '-pf_monitor',
                  '-pf_output', stopped])
    run.wait_for(run.MID_STAGE1)
    # Rank 0, which writes the checkpoint, learns of the signal from the poll.
    run.signal_ranks(signal.SIGTERM, ranks=(1,))
    status, out, err = run.finish()

    assert status == 128 + signal.SIGTERM, err
    assert 'stage1:' not in out  # it stopped inside stage 1
    errors = [line for line in err.splitlines() if line.startswith('pfmembrane')]
    assert errors == [f"pfmembrane: interrupted by SIGTERM (checkpoint {stopped} "
                      "marked converged = 0)"], err
    assert 'Traceback' not in err
    a, _ = _energy(stopped)
    assert a['converged'] == 0 and np.isfinite(a['energy'])

    path = str(tmp_path / 'restarted.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_restart', stopped,
              '-pf_output', path)
    assert out.returncode == 0, out.stderr
    b, _ = _energy(path)
    assert b['converged'] == 1
    assert abs(b['energy'] / _energy(res[2])[0]['energy'] - 1) < 1e-8


@pytest.mark.mpi
def test_dumbbell_options_file_runs(tmp_path, pfm):
    path = str(tmp_path / 'dumb.h5')
    out = pfm('-options_file', 'options/dumbbell.opts', '-pf_nodes', '1200', '-pf_box', '0.6,2.0',
              '-pf_eps', '0.06', '-pf_output', path)
    assert out.returncode == 0, out.stderr
    a, phi = _energy(path)
    with h5py.File(path, 'r') as f:
        nodes = f['nodes'][:]
    # Prolate: the vesicle is taller than wide (phi > 0 on the axis further from z_c).
    inside = nodes[phi > 0]
    assert np.ptp(inside[:, 1]) > 2 * inside[:, 0].max()
    assert a['converged'] == 1


@pytest.mark.mpi
@pytest.mark.parametrize('extra, status', [([], 2), (['-options_left'], 0)],
                         ids=['refused', 'options_left'])
def test_an_unused_option_is_refused_after_the_run(runs, tmp_path, extra, status, pfm):
    _, res = runs
    path = str(tmp_path / 'unused.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_restart', res[2],
              '-pf_output', path, '-stage2_snes_fake', '1', *extra)
    assert out.returncode == status, out.stderr
    errors = [line for line in out.stderr.splitlines() if line.startswith('pfmembrane')]
    if extra:  # PETSc's own report, as a warning
        assert errors == [] and 'Option left: name:-stage2_snes_fake' in out.stdout
    else:
        assert len(errors) == 1 and '-stage2_snes_fake never used' in errors[0], out.stderr
    assert _energy(path)[0]['converged'] == 1  # the result itself is kept


@pytest.mark.mpi
def test_half_box_solve_equals_the_full_box(tmp_path, pfm):
    """The mirror plane z = Zb/2 and no moment constraint: on a lattice that is
    its own mirror image, the same energy and multipliers from half the nodes."""
    scene = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '1100', '-pf_eps', '0.07']
    result = {}
    for half in (False, True):
        path = str(tmp_path / f'half{int(half)}.h5')
        out = pfm(*scene, '-pf_symmetric', str(half).lower(), '-pf_output', path)
        assert out.returncode == 0, out.stderr
        result[half] = _energy(path)[0]
    full, half = result[False], result[True]
    assert half['symmetric'] == 1 and full['symmetric'] == 0
    assert 2 * half['n_nodes'] < full['n_nodes'] + 60  # the plane's row is shared
    for name in ('energy', 'area', 'volume', 'nu_area', 'nu_volume'):
        assert abs(half[name] / full[name] - 1) < 1e-7, name
    assert half['moment'] == 0.0 and half['nu_moment'] == 0.0


@pytest.mark.mpi
def test_a_tight_box_is_reported_and_an_auto_restart_keeps_its_box(tmp_path, pfm):
    tight, again = str(tmp_path / 'tight.h5'), str(tmp_path / 'again.h5')
    scene = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '600', '-pf_eps', '0.06']
    out = pfm(*scene, '-pf_box', '0.7,0.8', '-pf_output', tight)
    assert out.returncode == 0, out.stderr
    a, _ = _energy(tight)
    assert a['boundary_phi'] > -1 + 1e-3
    assert 'constrains the vesicle' in out.stdout
    out = pfm(*scene, '-pf_box', 'auto', '-pf_restart', tight, '-pf_output', again)
    assert out.returncode == 0, out.stderr
    b, _ = _energy(again)
    assert list(b['box']) == [0.7, 0.8]
    assert abs(b['energy'] / a['energy'] - 1) < 1e-8
