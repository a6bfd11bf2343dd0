"""The README's commands as printed, in a fresh shell (no variable exported
but PATH and HOME): the command-line quick start and the Python quick start,
whose energy equals the command line's. They run in a scratch directory that
links the checkout's .venv and options/, so that they write no tracked file."""
import os
import re
import shlex
import subprocess

import h5py
import pytest

pytestmark = [pytest.mark.slow, pytest.mark.mpi]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
FRESH = {'PATH': '/usr/local/bin:/usr/bin:/bin', 'HOME': os.environ.get('HOME', '/root')}


def readme():
    with open(os.path.join(ROOT, 'README.md')) as f:
        return f.read()


def block(language):
    """The first fenced block of `language` in the README."""
    return re.search(rf'^```{language}\n(.*?)^```', readme(), flags=re.M | re.S).group(1)


def fresh(cmd, cwd):
    return subprocess.run(cmd, cwd=cwd, env=FRESH, capture_output=True, text=True, shell=True,
                          timeout=600)


@pytest.fixture(scope='module')
def scratch(tmp_path_factory):
    """A directory laid out like the checkout for the README's relative paths."""
    where = tmp_path_factory.mktemp('readme')
    for name in ('.venv', 'options'):
        (where / name).symlink_to(os.path.join(ROOT, name))
    # the study script the quick start runs, at its place in the checkout
    script = os.path.join('runs', 'modes', 'modes.py')
    (where / script).parent.mkdir(parents=True)
    (where / script).symlink_to(os.path.join(ROOT, script))
    return where


@pytest.fixture(scope='module')
def command_lines(scratch):
    """The quick start's commands (after `make install`), run in order."""
    lines = [line.split('  #')[0].strip() for line in block('sh').splitlines()]
    lines = [line for line in lines if line and not line.startswith('make ')]
    return [(line, fresh(line, scratch)) for line in lines]


def test_every_command_line_of_the_quick_start_works_in_a_fresh_shell(command_lines, scratch):
    assert len(command_lines) >= 4
    for line, done in command_lines:
        assert done.returncode == 0, f"{line}\n{done.stderr[-2000:]}"
    outputs = {line: done.stdout for line, done in command_lines}
    run = next(o for line, o in outputs.items() if line.endswith('options/discocyte.opts'))
    assert re.search(r'^result: E 9\.\d+ .* converged 1', run, flags=re.M)
    assert any('-pf_eps' in o and 'Exit status' in o for o in outputs.values())  # -help
    monitored = next(o for line, o in outputs.items() if '-log_view' in line)
    assert 'SNES Function norm' in monitored and 'pfStage2' in monitored
    modes = next(o for line, o in outputs.items() if 'modes/modes.py' in line)
    assert re.search(r'^\| 2 \| 1 \| -', modes, flags=re.M)  # the coarse oblate: m = 2 unstable
    assert (scratch / 'runs' / 'modes' / 'coarse_modes.png').exists()


def test_the_python_quick_start_prints_the_command_line_energy(command_lines, scratch, tmp_path):
    script = tmp_path / 'quickstart.py'
    script.write_text(block('python'))
    done = fresh(f"{ROOT}/.venv/bin/mpiexec -n 2 {ROOT}/.venv/bin/python "
                 f"{shlex.quote(str(script))}", scratch)
    assert done.returncode == 0, done.stderr[-2000:]
    energy = float(re.search(r'^E = (\S+)', done.stdout, flags=re.M).group(1))
    with h5py.File(scratch / 'runs' / 'discocyte.h5') as f:  # the run line's checkpoint
        assert energy == pytest.approx(float(f.attrs['energy']), rel=1e-10)
    assert (scratch / 'runs' / 'quickstart.xdmf').exists()
    assert re.search(r'set-up 0\.0 s', done.stdout)  # the second solve reused the grid


def test_the_options_table_lists_every_application_option():
    from pfmembrane.io.options import HELP
    listed = re.findall(r'^\| `-pf_(\w+)` \|', readme(), flags=re.M)
    assert sorted(listed) == sorted(HELP)
