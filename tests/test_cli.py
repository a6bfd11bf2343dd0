"""The command line: help, bad input, 1 vs 2 ranks, restart (real mpiexec runs)."""
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1',
           OMPI_MCA_rmaps_base_oversubscribe='1', OMPI_MCA_btl_vader_single_copy_mechanism='none')
SMALL = ['-pf_nodes', '1000', '-pf_box', '0.8,1.0', '-pf_eps', '0.06']


def pfm(*args, n=2, timeout=240):
    cmd = ['mpiexec', '-n', str(n), sys.executable, '-m', 'pfmembrane', *args]
    return subprocess.run(cmd, cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=timeout)


def test_help_lists_the_application_options():
    out = pfm('-help', n=1)
    assert out.returncode == 0
    for name in ('eps', 'k', 'c0', 'radius', 'reduced_volume', 'box', 'branch', 'nodes',
                 'gamma', 'restart', 'adapt', 'output', 'cutoff'):
        assert f'-pf_{name}' in out.stdout


@pytest.mark.parametrize('args, message', [
    (['-pf_eps', '-0.01'], 'pf_eps must be > 0'),
    (['-pf_eps', 'abc'], "cannot read 'abc'"),
    (['-pf_reduced_volume', '1.2'], 'reduced_volume must lie in (0, 1]'),
    (['-pf_reduced_volume', 'nan'], 'finite'),
    (['-pf_branch', 'torus'], "unknown shape 'torus'"),
    (['-pf_box', '0.5,0.6'], 'cannot hold the oblate vesicle'),
    (['-pf_nodes', '50'], 'too few'),
    (['-pf_eps', '0.03'], 'below what this grid resolves'),
    (['-pf_restart', '/nonexistent/x.h5'], 'no such file'),
])
def test_bad_input_is_one_line_and_nonzero_on_every_rank(args, message):
    out = pfm('-options_file', 'options/discocyte.opts', '-pf_nodes', '1500', *args)
    assert out.returncode == 2, out.stderr
    errors = [line for line in out.stderr.splitlines() if line.startswith('pfmembrane')]
    assert len(errors) == 1 and message in errors[0], out.stderr
    assert 'Traceback' not in out.stderr


def _energy(path):
    with h5py.File(path, 'r') as f:
        return dict(f.attrs), f['phi'][:]


@pytest.fixture(scope='module')
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp('cli')
    res = {}
    for n in (1, 2):
        path = str(d / f'disc{n}.h5')
        out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_output', path, n=n)
        assert out.returncode == 0, out.stderr
        res[n] = path
    return d, res


def test_one_and_two_ranks_agree(runs):
    _, res = runs
    a1, phi1 = _energy(res[1])
    a2, phi2 = _energy(res[2])
    assert a1['converged'] == 1 and a2['converged'] == 1
    assert a2['n_procs'] == 2
    assert abs(a1['energy'] / a2['energy'] - 1) < 1e-8
    assert np.max(np.abs(phi1 - phi2)) < 1e-6
    for key in ('energy', 'area', 'volume', 'moment', 'eps', 'k', 'c0', 'gamma', 'nu_area',
                'nu_volume', 'converged', 'wall_time', 'n_procs'):
        assert key in a2
    # Constraints met to 1e-8 relative at the end of stage 2; tension > 0, pressure < 0.
    R = 0.4
    assert abs(a2['area'] / (4 * np.pi * R ** 2) - 1) < 1e-8
    assert abs(a2['volume'] / (0.8 * 4 / 3 * np.pi * R ** 3) - 1) < 1e-8
    assert a2['nu_area'] > 0 and a2['nu_volume'] < 0


def test_restart_reaches_the_same_answer(runs):
    d, res = runs
    path = str(d / 'restarted.h5')
    out = pfm('-options_file', 'options/discocyte.opts', *SMALL, '-pf_restart', res[2],
              '-pf_output', path)
    assert out.returncode == 0, out.stderr
    a, _ = _energy(path)
    assert abs(a['energy'] / _energy(res[2])[0]['energy'] - 1) < 1e-8
    assert a['stage1_iterations'] <= 3  # it starts at the answer


def test_dumbbell_options_file_runs(tmp_path):
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
