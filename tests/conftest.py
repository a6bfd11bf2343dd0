"""What the tests share: the repository's paths, the environment of child runs, the
launching of those runs, and the markers.

Markers (registered in pyproject.toml; `make test-fast` runs `-m "not slow and not mpi"`):
    slow  the test starts a child process (the application, mpiexec, a Python interpreter:
          a second or more each) or spends more than ~2 s;
    mpi   the test launches mpiexec with more than one rank.
A test not marked slow that takes more than UNMARKED seconds is named at the end of the run.

The helpers are fixtures: tests/parallel/conftest.py is a module `conftest` too, so a
test module cannot import this one by name.
    root        the repository (a Path): options files are named relative to it
    child_env   the environment of a child process, a fresh dict
    mpi_env     MPI_ENV set in os.environ, for drivers run in this process
    in_root     mpi_env, with the repository as working directory
    python      python(*args): this interpreter in a child process
    mpiexec     mpiexec(*args, n=2): this interpreter on n ranks
    pfm         pfm(*args, n=2): the application on n ranks, as the drivers launch it
    mpirun      mpirun(args): a 2-rank `Run` of the application to act on as it runs
    on_groups   on_groups(module, *args): a driver (module or script path) on one rank, then
                on two groups of one
    md_tables   md_tables(text): the markdown tables of a generated page, cells by column

Under pytest-xdist each worker gets an Open MPI session directory of its own (see
_own_ompi_session_dir).
"""
import atexit
import contextlib
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import pytest


def _own_ompi_session_dir():
    """Under pytest-xdist, give this worker an Open MPI session directory of its own.

    Open MPI 4.1 puts the session directory of a singleton (MPI initialised in this process)
    and of mpiexec under `orte_tmpdir_base` (default /tmp) as ompi.<host>.<uid>; two workers
    initialising MPI at once on a clean machine race to create it ("File exists") and one
    dies in MPI_Init_thread. This runs when pytest loads this conftest, before any test
    module imports mpi4py or petsc4py; children (mpiexec, their ranks) inherit the variable,
    so each worker's whole process tree stays in its own directory. A base set by the user
    is kept, with the worker's directory made inside it.
    """
    worker = os.environ.get('PYTEST_XDIST_WORKER')
    if not worker:
        return
    key = 'OMPI_MCA_orte_tmpdir_base'
    base = os.environ.get(key) or None
    if base:
        os.makedirs(base, exist_ok=True)
    path = tempfile.mkdtemp(prefix=f'ompi-{worker}-', dir=base)
    os.environ[key] = path
    # Registered before mpi4py/petsc4py register their finalisation, so it runs after it.
    atexit.register(shutil.rmtree, path, ignore_errors=True)


_own_ompi_session_dir()

ROOT = Path(__file__).resolve().parents[1]
# Open MPI as root, with more ranks than cores, and without the single-copy mechanism
# that containers refuse.
MPI_ENV = {'OMPI_ALLOW_RUN_AS_ROOT': '1', 'OMPI_ALLOW_RUN_AS_ROOT_CONFIRM': '1',
           'OMPI_MCA_rmaps_base_oversubscribe': '1',
           'OMPI_MCA_btl_vader_single_copy_mechanism': 'none'}
TIMEOUT = 240  # s, for a child run that has not ended
UNMARKED = 3.0  # s: a test not marked slow that takes longer is named at the end of the run
# The end of the first augmented-Lagrangian outer iteration (-pf_monitor): mid-stage 1.
MID_STAGE1 = re.compile(r'^\s*AL\s+1\s')


def child_env():
    """The environment of a child run: Python's copy of this process's (the C one holds,
    once MPI is initialised here, variables that make a child mpiexec fail at once; see
    pfmembrane.series), MPI_ENV, and this checkout first on PYTHONPATH."""
    env = dict(os.environ)
    env.update(MPI_ENV)
    env['PYTHONPATH'] = os.pathsep.join([str(ROOT), *filter(None, [env.get('PYTHONPATH')])])
    return env


def mpi_command(n, *args):
    """`mpiexec -n N python ARGS...` with this interpreter (pfmembrane.series.command
    with `-m MODULE` for ARGS)."""
    return ['mpiexec', '-n', str(n), sys.executable, *map(str, args)]


def _end(proc):
    """Take a child started in a session of its own down: SIGTERM first (mpiexec takes its
    ranks down; they run in process groups of their own, out of reach of a signal to its
    group), SIGKILL to its group 10 s later."""
    proc.terminate()
    try:
        proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


def run(cmd, cwd=ROOT, timeout=TIMEOUT):
    """subprocess.run(cmd, capture_output=True, text=True) in child_env(); a run that has not
    ended after `timeout` s is ended before TimeoutExpired is raised."""
    proc = subprocess.Popen(cmd, cwd=cwd, env=child_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:
        _end(proc)
        raise
    return subprocess.CompletedProcess(cmd, proc.returncode, out, err)


def python(*args, cwd=ROOT, timeout=TIMEOUT):
    """`python ARGS...` (this interpreter) in a child process."""
    return run([sys.executable, *map(str, args)], cwd=cwd, timeout=timeout)


def mpiexec(*args, n=2, cwd=ROOT, timeout=TIMEOUT):
    """`mpiexec -n N python ARGS...`."""
    return run(mpi_command(n, *args), cwd=cwd, timeout=timeout)


def pfm(*args, n=2, timeout=TIMEOUT):
    """`mpiexec -n N python -m pfmembrane ARGS...` in the repository, by the drivers'
    command line (pfmembrane.series.command)."""
    from pfmembrane import series as launch
    return run(launch.command(n, *map(str, args)), timeout=timeout)


class Run:
    """An `mpiexec -n 2` run whose output is read as it comes, so that a test can act at
    a given line; every wait has a deadline."""
    TIMEOUT = 120
    MID_STAGE1 = MID_STAGE1

    def __init__(self, args, program=('-m', 'pfmembrane')):
        self.proc = subprocess.Popen(mpi_command(2, *program, *args), cwd=ROOT, env=child_env(),
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        self.stdout, self.stderr, self.lines = [], [], queue.Queue()
        self.readers = [threading.Thread(target=self._drain, args=(stream, store), daemon=True)
                        for stream, store in ((self.proc.stdout, self.stdout),
                                              (self.proc.stderr, self.stderr))]
        for reader in self.readers:
            reader.start()

    def _drain(self, stream, store):
        for line in stream:
            store.append(line)
            if store is self.stdout:
                self.lines.put(line)

    def wait_for(self, pattern, timeout=TIMEOUT):
        """Block until stdout has a line matching `pattern`."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(deadline - time.monotonic(), 0.01))
            except queue.Empty:
                self.kill()
                pytest.fail(f"no line matching {pattern.pattern!r}:\n{''.join(self.stdout)}"
                            f"{''.join(self.stderr)}")
            if pattern.search(line):
                return

    def _pids(self):
        """{rank: pid} of the processes mpiexec started (Linux, Open MPI)."""
        pids = {}
        for entry in filter(str.isdigit, os.listdir('/proc')):
            try:
                with open(f'/proc/{entry}/stat') as f:
                    parent = int(f.read().rsplit(')', 1)[1].split()[1])
                if parent != self.proc.pid:
                    continue
                with open(f'/proc/{entry}/environ', 'rb') as f:
                    env = dict(item.split(b'=', 1)
                               for item in f.read().split(b'\0') if b'=' in item)
            except OSError:
                continue  # exited meanwhile
            if b'OMPI_COMM_WORLD_RANK' in env:
                pids[int(env[b'OMPI_COMM_WORLD_RANK'])] = int(entry)
        return pids

    def signal_ranks(self, signum, ranks=(0, 1)):
        pids = self._pids()
        if len(pids) != 2:
            self.kill()
            pytest.skip("the ranks of mpiexec cannot be found through /proc")
        for rank in ranks:
            os.kill(pids[rank], signum)

    def kill(self):
        for pid in self._pids().values():
            with contextlib.suppress(ProcessLookupError):  # it exited meanwhile
                os.kill(pid, signal.SIGKILL)
        self.proc.kill()

    def finish(self, timeout=TIMEOUT):
        """Exit status, stdout, stderr; a run that does not end fails the test."""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            self.proc.wait(10)
            pytest.fail(f"mpiexec did not end in {timeout} s:\n{''.join(self.stderr)}")
        for reader in self.readers:
            reader.join(10)
        return self.proc.returncode, ''.join(self.stdout), ''.join(self.stderr)


_unmarked = {}


def pytest_runtest_logreport(report):
    """The time of each test not marked slow: set-up, call and teardown."""
    if 'slow' not in report.keywords:
        _unmarked[report.nodeid] = _unmarked.get(report.nodeid, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter):
    """Name the tests that `make test-fast` runs but should not: unmarked and slow."""
    over = sorted(((t, name) for name, t in _unmarked.items() if t > UNMARKED), reverse=True)
    if over:
        terminalreporter.section(f'not marked slow, over {UNMARKED:g} s')
        for t, name in over:
            terminalreporter.write_line(f'{t:6.1f} s  {name}')


class Table:
    """A markdown table: `section` (the text of the last heading above it, '' if none),
    `header` (the column names; a name that repeats gets ' 2', ' 3' ... on its later
    columns) and `rows` (dicts column -> cell text, stripped)."""

    def __init__(self, section, lines):
        header, rule, *body = [[c.strip() for c in line.strip()[1:-1].split('|')]
                               for line in lines]
        assert set(''.join(rule)) <= set('-:') and len(rule) == len(header), lines[1]
        seen = {}
        for k, name in enumerate(header):
            seen[name] = seen.get(name, 0) + 1
            header[k] = name if seen[name] == 1 else f'{name} {seen[name]}'
        for line, cells in zip(lines[2:], body):
            assert len(cells) == len(header), line
        self.section, self.header = section, header
        self.rows = [dict(zip(header, cells)) for cells in body]

    def column(self, name, kind=float):
        return [kind(row[name]) for row in self.rows]

    def row(self, column, value):
        """The one row whose `column` reads `value`."""
        found = [row for row in self.rows if row[column] == value]
        assert len(found) == 1, (column, value, self.rows)
        return found[0]


def md_tables(text):
    """The markdown tables of `text`, in order, as `Table`s."""
    tables, block, section = [], [], ''
    for line in text.splitlines() + ['']:
        if line.startswith('|'):
            block.append(line)
            continue
        if block:
            tables.append(Table(section, block))
            block = []
        if line.startswith('#'):
            section = line.lstrip('#').strip()
    return tables


@pytest.fixture(scope='session', name='md_tables')
def _md_tables():
    """md_tables(text): the markdown tables of `text` (see `Table`), to check a generated
    page by the values in its cells rather than by its formatting."""
    return md_tables


@pytest.fixture(scope='session')
def root():
    return ROOT


@pytest.fixture(name='child_env')
def _child_env():
    return child_env()


@pytest.fixture
def mpi_env(monkeypatch):
    """MPI_ENV in os.environ, for a driver run in this process: its children inherit it."""
    for key, value in MPI_ENV.items():
        monkeypatch.setenv(key, value)


@pytest.fixture
def in_root(mpi_env, monkeypatch):
    """mpi_env, in the repository: the drivers name options files relative to it."""
    monkeypatch.chdir(ROOT)


@pytest.fixture
def on_groups(tmp_path, root):
    """on_groups(module, *args): the driver `python -m module args` (`python ROOT/module
    args` for a script path ending in .py, run from tmp_path) run on one rank into
    tmp_path/one, then on two ranks as two groups of one (`--groups 2`) into tmp_path/two,
    as a test launching its own mpiexec (skipped under one); returns the two directories
    and the second run's output. Each run must exit with 0."""
    from pfmembrane.series import under_mpiexec
    if under_mpiexec():
        pytest.skip('launches its own mpiexec')

    def run(module, *args):
        for n, out in ((1, 'one'), (2, 'two')):
            target = [str(root / module)] if module.endswith('.py') else ['-m', module]
            done = subprocess.run([sys.executable, *target, *args, '--np', str(n),
                                   '--groups', str(n), '--out', str(tmp_path / out)],
                                  cwd=tmp_path if module.endswith('.py') else root,
                                  env=child_env(), capture_output=True, text=True,
                                  timeout=600)
            assert done.returncode == 0, done.stderr[-2000:]
        assert '[group 1]' in done.stdout
        return tmp_path / 'one', tmp_path / 'two', done.stdout
    return run


@pytest.fixture(scope='session', name='python')
def _python():
    return python


@pytest.fixture(scope='session', name='mpiexec')
def _mpiexec():
    return mpiexec


@pytest.fixture(scope='session', name='pfm')
def _pfm():
    return pfm


@pytest.fixture
def mpirun():
    """Run(args, program=('-m', 'pfmembrane')); what is still running at the end is killed."""
    started = []

    def start(args, program=('-m', 'pfmembrane')):
        started.append(Run(args, program))
        return started[-1]

    yield start
    for each in started:
        if each.proc.poll() is None:
            each.kill()
            each.proc.wait(10)
