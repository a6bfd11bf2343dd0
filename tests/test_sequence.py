"""The adaptive-sequence driver: steps run in order and restart from each other,
converged steps are reused, a step whose start failed is skipped, and the table
compares each checkpoint with the paper's column for its grid."""
import numpy as np
import pytest

from scripts import load
from pfmembrane.io import checkpoint
from pfmembrane import series as launch
from pfmembrane.paper import SHARP, SHARP_ERROR

sequence = load('runs/adapt/sequence.py')

SMALL = '-pf_nodes 1000\n-pf_box 0.8,1.0\n-pf_eps 0.06\n'


def steps(tmp):
    """A uniform solve, a CVT relocation restarting from it, and a step whose
    start never converged."""
    files = {
        '01_U_eps0.06.opts': f'{SMALL}-pf_output {tmp}/U_eps0.06.h5\n',
        '02_A_eps0.06.opts': (f'{SMALL}-pf_stage1 none\n-pf_restart {tmp}/U_eps0.06.h5\n'
                              f'-pf_adapt 10\n-pf_output {tmp}/A_eps0.06.h5\n'),
        '03_B_eps0.05.opts': (f'{SMALL}-pf_restart {tmp}/never.h5\n-pf_eps 0.05\n'
                              f'-pf_output {tmp}/B_eps0.05.h5\n'),
    }
    for name, text in files.items():
        (tmp / name).write_text(text)
    return tmp


@pytest.mark.slow
def test_a_sequence_runs_reuses_and_skips(tmp_path, in_root, capfd, md_tables):
    directory = steps(tmp_path)
    out = tmp_path / 'table.md'
    argv = [str(directory), '--scene', 'options/discocyte.opts', '--np', '1', '--out', str(out)]

    assert sequence.main(argv) == 1  # step 03 did not run
    first = capfd.readouterr().out  # PETSc prints through the C stdout
    assert '03_B_eps0.05.opts: not run, its start' in first
    assert not (tmp_path / 'B_eps0.05.h5').exists()
    table, = md_tables(out.read_text())
    assert table.column('grid', str) == ['U', 'A']
    assert table.column('converged', int) == [1, 1]
    # Both steps ran here: the last column has their wall time, a number.
    assert all(wall > 0 for wall in table.column('wall s'))
    adapted = checkpoint.read(tmp_path / 'A_eps0.06.h5')
    assert adapted.attrs['converged'] == 1
    # the relocation kept the count and concentrated the nodes: a finer spacing
    uniform = checkpoint.read(tmp_path / 'U_eps0.06.h5')
    assert adapted.attrs['n_nodes'] == uniform.attrs['n_nodes']
    assert adapted.attrs['eps_min'] < uniform.attrs['eps_min']

    assert sequence.main(argv) == 1
    second = capfd.readouterr().out
    assert 'pfmembrane: oblate' not in second  # nothing converged runs again
    table, = md_tables(out.read_text())
    assert table.column('grid', str) == ['U', 'A']
    assert table.column('wall s', str) == ['reused', 'reused']


@pytest.mark.slow
def test_a_half_box_adaptive_sequence_in_process_equals_one_run_per_step(tmp_path, in_root):
    # Two relocations of a half-box solve (the mirror plane's nodes leave it): the
    # in-process sequence and one command-line run per step agree far below 1e-8.
    half = f'{SMALL}-pf_symmetric\n'
    files = {'01_U.opts': f'-pf_output {tmp_path}/U.h5\n',
             '02_A.opts': f'-pf_stage1 none\n-pf_restart {tmp_path}/U.h5\n-pf_adapt 100\n'
                          f'-pf_output {tmp_path}/A.h5\n',
             '03_B.opts': f'-pf_stage1 none\n-pf_restart {tmp_path}/A.h5\n-pf_adapt 1000\n'
                          f'-pf_eps 0.05\n-pf_output {tmp_path}/B.h5\n'}
    for name, text in files.items():
        (tmp_path / name).write_text(half + text)
    assert sequence.main([str(tmp_path), '--scene', 'options/discocyte.opts', '--np', '1',
                          '--out', str(tmp_path / 'table.md')]) == 0
    inproc = {k: checkpoint.read(tmp_path / f'{k}.h5') for k in 'UAB'}
    for name in sorted(files):
        done = launch.run(launch.command(1, '-options_file', 'options/discocyte.opts',
                                         '-options_file', str(tmp_path / name)),
                          check=False, capture_output=True)
        assert done.returncode == 0, done.stderr
    for k, a in inproc.items():
        b = checkpoint.read(tmp_path / f'{k}.h5')
        assert a.attrs['converged'] == b.attrs['converged'] == 1
        assert abs(b.attrs['energy'] / a.attrs['energy'] - 1.0) < 1e-10
    plane = 0.5 * inproc['U'].attrs['box'][1]
    assert (inproc['U'].nodes[:, 1] == plane).sum() > 10
    assert (inproc['B'].nodes[:, 1] == plane).sum() == 2  # the corners only


def fake_checkpoint(path, n_nodes, symmetric, eps=0.01, energy=9.18):
    """A checkpoint of an oblate run with the attributes a table row reads (and those
    every checkpoint has), on three nodes."""
    attrs = dict(branch='oblate', eps=eps, energy=energy, n_nodes=n_nodes,
                 symmetric=int(symmetric), gamma=0.5, eps_min=0.004, max_phi=1.0,
                 stage1_iterations=3, stage2_iterations=2, converged=1, time_setup=1.0,
                 time_stage1=2.0, time_stage2=1.0, peak_rss_mb=100.0, wall_time=4.0,
                 n_procs=2, area=2.0, volume=0.2, moment=0.0, k=1.0, c0=0.0, nu_area=1.0,
                 nu_volume=-1.0, box=(1.5, 2.0))
    checkpoint.write(path, np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), -np.ones(3), attrs)


@pytest.mark.parametrize('n_nodes, symmetric, paper', [(12262, False, 12271),
                                                      (12319, True, 24597),
                                                      (6176, True, 12271)])
def test_the_table_compares_a_half_box_with_its_full_box_grid(tmp_path, n_nodes, symmetric,
                                                              paper):
    path = tmp_path / 'O32_eps0.01.h5'
    fake_checkpoint(path, n_nodes, symmetric)
    step = tmp_path / '07_O32_eps0.01.opts'
    step.write_text(f'-pf_output {path}\n')

    rows, total, ranks = sequence.table([str(step)], {})

    cells = rows[-1].split(' | ')
    assert cells[11] == f'{100 * (9.18 / SHARP["oblate"] - 1):.2f}%'
    assert cells[12] == f'{SHARP_ERROR[paper][0.01]:.2f}%'
    assert (total, ranks) == (4.0, [2])


def test_a_deadline_is_the_next_such_time_and_stays_put():
    # --until HH:MM is the first HH:MM after the study starts: one a minute gone is
    # tomorrow's, and once fixed it does not move on as the clock passes it
    import datetime
    now = datetime.datetime.now(datetime.timezone.utc)
    gone = (now - datetime.timedelta(minutes=1)).strftime('%H:%M')
    assert 23 * 3600 < launch.seconds_left(gone) <= 24 * 3600
    assert launch._deadline(gone) is launch._deadline(gone)
    assert launch.seconds_left(None) == float('inf')
