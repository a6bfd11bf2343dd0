"""Faults: SIGTERM and SIGINT are recorded and raised at the collective poll,
a second signal ends the process at once; in real `mpiexec -n 2` runs of the
small scene, SIGKILL leaves the previous checkpoint intact and an exception on
one rank aborts all. The `mpirun` fixture (conftest.Run) drives such runs (test_cli
interrupts one with SIGTERM and restarts from its checkpoint)."""
import os
import re
import signal
import time

import numpy as np
import pytest
from mpi4py import MPI

from pfmembrane.io import checkpoint
from pfmembrane.parallel import faults

SCENE = ['-options_file', 'options/discocyte.opts', '-pf_nodes', '1000', '-pf_box', '0.8,1.0',
         '-pf_eps', '0.06']
TIMEOUT = 120

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


@pytest.mark.slow
def test_a_second_signal_ends_the_process_at_once(python):
    code = ('import os, signal, time\n'
            'from pfmembrane.parallel import faults\n'
            'faults.install()\n'
            'os.kill(os.getpid(), signal.SIGTERM)\n'
            'print("recorded", flush=True)\n'
            'os.kill(os.getpid(), signal.SIGTERM)\n'
            'time.sleep(30)\n')
    out = python('-c', code, timeout=TIMEOUT)
    assert out.stdout == 'recorded\n' and out.returncode == -signal.SIGTERM, out.stderr


@pytest.mark.slow
@pytest.mark.mpi
def test_sigkill_leaves_the_previous_checkpoint(tmp_path, mpirun):
    path = tmp_path / 'state.h5'
    nodes = np.random.default_rng(0).uniform((0.0, 0.0), (0.8, 1.0), (300, 2))
    attrs = {key: 1.0 for key in checkpoint.FLOAT_ATTRS}
    checkpoint.write(path, nodes, np.zeros(300), dict(attrs, converged=1, box=(0.8, 1.0)))
    before = path.read_bytes()

    run = mpirun([*SCENE, '-pf_monitor', '-pf_output', str(path)])
    run.wait_for(run.MID_STAGE1)
    run.signal_ranks(signal.SIGKILL)
    status, _, _ = run.finish()

    assert status != 0
    assert path.read_bytes() == before
    assert checkpoint.read(path).attrs['converged'] == 1
    assert os.listdir(tmp_path) == ['state.h5']


@pytest.mark.slow
@pytest.mark.mpi
def test_an_exception_on_one_rank_aborts_both(tmp_path, mpirun):
    run = mpirun([*SCENE, '-pf_output', str(tmp_path / 'never.h5')],
                 program=('-c', FAULT_ON_RANK_1))
    status, out, err = run.finish()
    ended = time.time()

    assert status != 0
    assert 'result:' not in out and not os.path.exists(tmp_path / 'never.h5')
    assert 'pfmembrane: rank 1: RuntimeError: injected fault' in pf_lines(err), err
    assert 'Traceback' not in err
    fault = float(re.search(r'fault at ([0-9.]+)', err).group(1))
    assert ended - fault < 10, f"{ended - fault:.1f} s from the fault to the end of mpiexec"
