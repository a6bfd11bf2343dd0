"""The stability study driver (`runs/extremes/extremes.py`): two cheap cases through real mpiexec
runs, and the verdicts and table cells of synthetic rows."""
import json
import math

import pytest

from scripts import load

extremes = load('runs/extremes/extremes.py')


@pytest.fixture
def elsewhere(mpi_env, tmp_path, monkeypatch):
    """mpi_env, with a working directory outside the repository: the study finds its
    options files from its own path."""
    monkeypatch.chdir(tmp_path)


def table_rows(path):
    """The data rows of the study's table, by case name, as dicts of header -> cell."""
    lines = path.read_text().splitlines()
    start = lines.index('| ' + ' | '.join(extremes.HEADER) + ' |')
    rows = [[cell.strip() for cell in line.strip('|').split(' | ')]
            for line in lines[start + 2:] if line.startswith('|')]
    return {row[0]: dict(zip(extremes.HEADER, row)) for row in rows}


@pytest.mark.slow
@pytest.mark.mpi
def test_refused_and_tiny_cases(tmp_path, elsewhere):
    # eps0.04: below the 3000-node grid's eps_min, refused after the grid is built;
    # box-tight: 936 nodes, a few seconds of solves, the membrane against the box.
    status = extremes.main(['--out', str(tmp_path), '--only', 'eps0.04,box-tight'])
    assert status == 0
    rows = table_rows(tmp_path / 'extremes.md')
    assert list(rows) == ['eps0.04', 'box-tight']
    title, _, provenance = (tmp_path / 'extremes.md').read_text().splitlines()[:3]
    assert title == f"# {extremes.TITLE}" and provenance.startswith('Measured at commit')
    assert 'runs/extremes/extremes.py --out' in provenance

    refused = rows['eps0.04']
    assert refused['exit'] == '2' and refused['expected'] == 'refused: yes'
    assert refused['verdict'].startswith('refused: eps 0.04 is below what this grid resolves')
    assert refused['E'] == '—' and refused['converged'] == '—'
    # The ratio comes from the grid line of the refused run (eps_min 0.05167).
    assert float(refused['eps/eps_min']) == pytest.approx(0.04 / 0.05167, abs=1e-3)
    assert not (tmp_path / 'eps0.04.h5').exists()

    tight = rows['box-tight']
    assert tight['exit'] == '0' and tight['converged'] == '1' and tight['under-resolved'] == '0'
    assert tight['grid'] == 'uniform, 936 in 0.7 x 1'
    assert tight['verdict'].startswith('converged, phi_h -0.9')
    assert tight['verdict'].endswith('one eps inside the box')
    assert tight['expected'] == 'box-dependent: yes'
    its = tight['its (1+2)'].split('+')
    assert all(int(n) > 0 for n in its)
    # Stage 2 solves the constraints to rounding.
    assert abs(float(tight['dA/A0'])) < 1e-10 and abs(float(tight['dV/V0'])) < 1e-10
    assert float(tight['max abs phi'].split()[0]) > 1.0

    data = json.loads((tmp_path / 'extremes.json').read_text())
    by_name = {row['name']: row for row in data['rows']}
    assert by_name['box-tight']['boundary_phi'] > -1 + extremes.BOUNDARY_TOL
    assert by_name['eps0.04']['reason'].startswith('eps 0.04 is below')
    assert json.loads((tmp_path / 'box-tight.json').read_text())['status'] == 0


@pytest.mark.slow
@pytest.mark.mpi
def test_a_run_past_its_time_limit_is_stopped_and_reported(tmp_path, elsewhere):
    status = extremes.main(['--out', str(tmp_path), '--only', 'box-tight', '--timeout', '1'])
    assert status == 1   # box-dependent expected, a failure found
    row = table_rows(tmp_path / 'extremes.md')['box-tight']
    assert row['verdict'] == 'failed: timed out after 1 s'
    assert row['expected'] == 'box-dependent: NO'
    record = json.loads((tmp_path / 'box-tight.json').read_text())
    assert record['timed_out'] and record['status'] != 0


def synthetic(**changes):
    """A converged row of a v = 0.8, R = 0.4 scene, as `measure` makes it."""
    case = extremes.BY_NAME['box-paper']
    row = extremes.blank_row(case)
    row.update(status=0, reason='', timeout=1200.0, seconds=20.0, grid='uniform, 2654 in 1 x 2',
               eps=0.05, eps_min=0.0449, energy=10.2, versus_energy=9.75, versus_box=[1.5, 2.0],
               box=[1.0, 2.0], radius=0.4, sharp_energy=9.12657, sharp_rel_error=0.1176,
               sharp_dist_max=0.026, level_set_v=0.769, level_set_pieces=1,
               stage1_iterations=19, stage2_iterations=3, max_phi=1.004,
               area_residual=2e-15, volume_residual=-3e-16, boundary_phi=-1.0033,
               wall_time=14.8, converged=1, under_resolved=0)
    row.update(changes)
    return extremes.finish(row)


def test_verdicts_and_cells_of_synthetic_rows():
    box = synthetic()
    assert box['verdict'] == 'converged, E +4.62% vs box-roomy in a 1.5 x 2 box'
    assert box['as_expected']
    cells = dict(zip(extremes.HEADER, extremes.cells(box)))
    assert cells['E vs'] == '+4.615% vs box-roomy'
    assert cells['max abs phi'] == '1.0040 (+0.40%)'
    assert cells['dA/A0'] == '+2.0e-15' and cells['dV/V0'] == '-3.0e-16'
    assert cells['its (1+2)'] == '19+3' and cells['eps/eps_min'] == '1.114'
    assert cells['vs sharp'] == '+11.76%' and cells['v of phi_h=0'] == '0.7690'
    assert cells['expected'] == 'box-dependent: yes'

    # Within BOX_TOL of the roomy box and clear of it: plainly converged, not what box-paper expects.
    plain = synthetic(energy=9.76)
    assert plain['verdict'] == 'converged' and not plain['as_expected']

    flagged = synthetic(under_resolved=1, eps=0.04, sharp_dist_max=0.2, boundary_phi=-0.98)
    assert flagged['verdict'] == (
        'converged, under-resolved (eps/eps_min 0.89), phi_h -0.9800 one eps inside the box, '
        'E +4.62% vs box-roomy in a 1.5 x 2 box, phi_h = 0 up to 0.200 from the sharp-interface shape')

    failed = synthetic(status=1, converged=0, reason='stage 2 Newton did not converge (SNES reason -6)')
    assert failed['verdict'] == 'failed: stage 2 Newton did not converge (SNES reason -6)'
    assert not failed['as_expected']
    silent = synthetic(status=4, reason='')
    assert silent['verdict'] == 'failed: exit status 4 without a reason on stderr'
    late = synthetic(status=143, timed_out=True, reason='interrupted by SIGTERM',
                     stage1_iterations=-1, stage2_iterations=-1)
    assert late['verdict'] == 'failed: timed out after 1200 s'
    assert dict(zip(extremes.HEADER, extremes.cells(late)))['its (1+2)'] == '—+—'

    refused = extremes.finish(dict(extremes.blank_row(extremes.BY_NAME['box-small']), status=2,
                                   reason='-pf_box 0.6,2 cannot hold the oblate vesicle'))
    assert refused['verdict'] == 'refused: -pf_box 0.6,2 cannot hold the oblate vesicle'
    assert refused['as_expected']
    cells = extremes.cells(refused)
    assert cells[extremes.HEADER.index('E')] == '—'

    orphan = extremes.not_run(extremes.BY_NAME['graded-eps0.02'], 'needs graded-f1000, which has '
                                                                  'no converged checkpoint')
    assert orphan['verdict'].startswith('not run: needs graded-f1000') and not orphan['as_expected']


def test_reported_cases_need_a_stated_reason():
    case = extremes.BY_NAME['gamma6']
    row = dict(extremes.blank_row(case), status=1, reason='')
    assert not extremes.finish(row)['as_expected']
    row['reason'] = 'stage 1 did not reach constraint residual 0.001'
    assert extremes.finish(row)['as_expected']


def test_case_table():
    names = [case.name for case in extremes.CASES]
    assert len(set(names)) == len(names)
    for i, case in enumerate(extremes.CASES):
        assert case.expect in extremes.EXPECT
        for other in (case.parent, case.versus):
            assert not other or other in names[:i], (case.name, other)
    assert [c.name for c in extremes.select(['graded-eps0.02'])] == [
        'reference', 'graded-f1000', 'graded-eps0.02']
    with pytest.raises(ValueError, match='unknown case nope'):
        extremes.select(['nope'])


def test_reason_and_eps_min_are_read_from_the_output():
    stderr = ('pfmembrane: stage 2 Newton did not converge (SNES reason -6); try a tighter stage 1 '
              '(checkpoint runs/x.h5 marked converged = 0)\n'
              '--------------------------------------------------\n'
              'mpiexec detected that one or more processes exited with non-zero status\n')
    assert extremes.reason_line(stderr) == ('stage 2 Newton did not converge (SNES reason -6); '
                                            'try a tighter stage 1')
    assert extremes.reason_line('pfmembrane: error: -pf_eps must be > 0 (got -1.0)\n') == \
        '-pf_eps must be > 0 (got -1.0)'
    assert extremes.reason_line('') == ''
    stdout = 'grid: 2994 nodes (2838 free), 34782 quadrature points, eps_min 0.05167, set-up 3 s\n'
    assert math.isclose(extremes.printed_eps_min(stdout), 0.05167)
    assert extremes.printed_eps_min('pfmembrane: oblate eps=0.06\n') is None
