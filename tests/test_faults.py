"""Faults: SIGTERM and SIGINT are recorded and raised at the collective poll,
a second signal ends the process at once; in real `mpiexec -n 2` runs of the
small scene, SIGKILL leaves the previous checkpoint intact and an exception on
one rank aborts all. `Run` drives such runs (test_cli interrupts one with
SIGTERM and restarts from its checkpoint)."""
import contextlib
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
from mpi4py import MPI

from pfmembrane.io import checkpoint
from pfmembrane.parallel import faults

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1',
           OMPI_MCA_rmaps_base_oversubscribe='1', OMPI_MCA_btl_vader_single_copy_mechanism='none')
SCENE = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '1000', '-pf_box', '0.8,1.0',
         '-pf_eps', '0.06']
TIMEOUT = 120
# The end of the first augmented-Lagrangian outer iteration (-pf_monitor): mid-stage 1.
MID_STAGE1 = re.compile(r'^\s*AL\s+1\s')

# Rank 1 only raises from its third functional evaluation, when rank 0 is
# inside the same collective computation; the time of the fault goes to stderr.
FAULT_ON_RANK_1 = """
import os, runpy, sys, time
if os.environ.get('OMPI_COMM_WORLD_RANK') == '1':
    import petsc4py
    petsc4py.init(sys.argv)
    from pfmembrane.parallel import solver
    evaluate, calls = solver.Solver.evaluate, []

    def faulty(self, x):
        calls.append(1)
        if len(calls) == 3:
            sys.stderr.write(f"fault at {time.time()!r}\\n")
            raise RuntimeError('injected fault')
        return evaluate(self, x)

    solver.Solver.evaluate = faulty
runpy.run_module('pfmembrane', run_name='__main__')
"""


class Run:
    """An `mpiexec -n 2` run whose output is read as it comes, so that a test
    can act at a given line; every wait has a deadline."""

    def __init__(self, args, program=('-m', 'pfmembrane')):
        cmd = ['mpiexec', '-n', '2', sys.executable, *program, *args]
        self.proc = subprocess.Popen(cmd, cwd=ROOT, env=ENV, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True)
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


def pf_lines(stderr):
    return [line for line in stderr.splitlines() if line.startswith('pfmembrane')]


@pytest.mark.parametrize('signum', faults.SIGNALS)
def test_a_signal_is_recorded_then_raised_at_the_poll(monkeypatch, signum):
    monkeypatch.setattr(faults, '_received', 0)
    previous = {s: signal.getsignal(s) for s in faults.SIGNALS}
    try:
        faults.install()
        faults.poll(MPI.COMM_SELF)
        os.kill(os.getpid(), signum)  # the handler runs before the next statement
        with pytest.raises(faults.Interrupted) as info:
            faults.poll(MPI.COMM_SELF)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    assert info.value.status == 128 + signum
    assert str(info.value) == f"interrupted by {signal.Signals(signum).name}"


def test_a_second_signal_ends_the_process_at_once():
    code = ('import os, signal, time\n'
            'from pfmembrane import faults\n'
            'faults.install()\n'
            'os.kill(os.getpid(), signal.SIGTERM)\n'
            'print("recorded", flush=True)\n'
            'os.kill(os.getpid(), signal.SIGTERM)\n'
            'time.sleep(30)\n')
    out = subprocess.run([sys.executable, '-c', code], cwd=ROOT, env=ENV, capture_output=True,
                         text=True, timeout=TIMEOUT)
    assert out.stdout == 'recorded\n' and out.returncode == -signal.SIGTERM, out.stderr


def test_sigkill_leaves_the_previous_checkpoint(tmp_path):
    path = tmp_path / 'state.h5'
    nodes = np.random.default_rng(0).uniform((0.0, 0.0), (0.8, 1.0), (300, 2))
    attrs = {key: 1.0 for key in checkpoint.FLOAT_ATTRS}
    checkpoint.write(path, nodes, np.zeros(300), dict(attrs, converged=1, box=(0.8, 1.0)))
    before = path.read_bytes()

    run = Run([*SCENE, '-pf_monitor', '-pf_output', str(path)])
    run.wait_for(MID_STAGE1)
    run.signal_ranks(signal.SIGKILL)
    status, _, _ = run.finish()

    assert status != 0
    assert path.read_bytes() == before
    assert checkpoint.read(path).attrs['converged'] == 1
    assert os.listdir(tmp_path) == ['state.h5']


def test_an_exception_on_one_rank_aborts_both(tmp_path):
    run = Run([*SCENE, '-pf_output', str(tmp_path / 'never.h5')],
              program=('-c', FAULT_ON_RANK_1))
    status, out, err = run.finish()
    ended = time.time()

    assert status != 0
    assert 'result:' not in out and not os.path.exists(tmp_path / 'never.h5')
    assert 'pfmembrane: rank 1: RuntimeError: injected fault' in pf_lines(err), err
    assert 'Traceback' not in err
    fault = float(re.search(r'fault at ([0-9.]+)', err).group(1))
    assert ended - fault < 10, f"{ended - fault:.1f} s from the fault to the end of mpiexec"
