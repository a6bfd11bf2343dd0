"""What the accuracy studies share: the command line run as a child process from the
repository root (its earlier step checkpoints removed first, so -pf_tol does not resume),
a deadline, and the text of its outcome for a table."""
import os
import shutil
import signal
import subprocess
import time

from pfmembrane import series

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(np_, args, output, limit=None):
    """(wall seconds, return code, stdout, stderr, killed) of the command line with `args` on
    `np_` ranks from ROOT, writing `output`, the step checkpoints of an earlier run of
    `output` removed first; stopped (its process group) after `limit` seconds."""
    shutil.rmtree(os.path.splitext(output)[0] + '_tol', ignore_errors=True)
    if os.path.exists(output):
        os.remove(output)
    t0 = time.perf_counter()
    child = subprocess.Popen(series.command(np_, *args, '-pf_output', output), cwd=ROOT,
                             env=series.environment(), stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    killed = False
    try:
        stdout, stderr = child.communicate(timeout=limit)
    except subprocess.TimeoutExpired:
        killed = True
        os.killpg(child.pid, signal.SIGTERM)
        try:
            stdout, stderr = child.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(child.pid, signal.SIGKILL)
            stdout, stderr = child.communicate()
    return time.perf_counter() - t0, child.returncode, stdout, stderr, killed


def clean(text):
    """`text` as one table cell."""
    return ' '.join(text.split()).replace('|', '/')


def last_line(text):
    """The message of a failure: the last line naming an error, else the last line that is
    not part of mpiexec's banner (dashes)."""
    lines = [t.strip() for t in text.splitlines() if t.strip().strip('-')]
    errors = [t for t in lines if 'error' in t.lower() or 'usage' in t.lower()]
    return clean((errors or lines or [''])[-1])


def steps(attrs):
    """The eps and the node counts of a -pf_tol run's steps, as table cells."""
    eps = ' '.join(f"{e:.3g}" for e in attrs['tol_eps']) if 'tol_eps' in attrs else '-'
    nodes = ' '.join(str(int(n)) for n in attrs['tol_nodes']) if 'tol_nodes' in attrs else '-'
    return eps, nodes
