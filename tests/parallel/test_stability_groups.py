"""The stability study (pfmembrane.studies.stability) on rank groups: two series on two
groups of one rank give the tables of one rank following both in turn."""
import re
import subprocess
import sys

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.mpi]

SMALL = ['--series', 'oblate', 'oblate_v0.8', '--count', '2', '--nodes', '1200', '--eps', '0.07',
         '--modes', '1']


def _rows(path):
    """The table rows without the iteration counts and the seconds: the summation order
    of threaded BLAS differs between the runs, which can move a count by a few where the
    solves on a coarse grid take 35-55 Newton steps; the printed values agree."""
    rows = [line.split('|')[1:-3] for line in path.read_text().splitlines()
            if re.match(r'^\| \d', line)]
    return [row[:7] + row[8:] for row in rows]


def test_two_groups_of_one_rank_give_the_one_rank_tables(tmp_path, child_env, root):
    from pfmembrane.studies.launch import under_mpiexec
    if under_mpiexec():
        pytest.skip('launches its own mpiexec')
    cmd = [sys.executable, '-m', 'pfmembrane.studies.stability', *SMALL]
    for np_, groups, out in ((1, 1, 'one'), (2, 2, 'two')):
        done = subprocess.run(cmd + ['--np', str(np_), '--groups', str(groups), '--out',
                                     str(tmp_path / out)], cwd=root, env=child_env,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
    assert '[group 1]' in done.stdout
    one, two = _rows(tmp_path / 'one' / 'branches.md'), _rows(tmp_path / 'two' / 'branches.md')
    assert len(one) == 4 and one == two
