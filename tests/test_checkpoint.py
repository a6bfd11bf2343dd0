"""Tests of pfmembrane.io.checkpoint: round trip, atomic replacement, rejection
of bad files, MPI collectivity and the XDMF description."""

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest

from pfmembrane.io import checkpoint
from pfmembrane.io.checkpoint import CheckpointError

BOX = (1.0, 2.0)
TIMEOUT = 60


def make_state(seed=0, n_extra=100):
    """Nodes (a grid with the box corners plus random points), an ellipse
    phase field and a complete set of attributes."""
    rng = np.random.default_rng(seed)
    rb, zb = BOX
    r, z = np.meshgrid(np.linspace(0.0, rb, 10), np.linspace(0.0, zb, 20))
    extra = rng.uniform((0.0, 0.0), BOX, size=(n_extra, 2))
    nodes = np.vstack([np.column_stack([r.ravel(), z.ravel()]), extra])
    eps = 0.05 + 0.01 * seed
    level = 1.0 - np.hypot(nodes[:, 0] / 0.5, (nodes[:, 1] - 1.0) / 0.8)
    phi = np.tanh(0.5 * level / (np.sqrt(2.0) * eps))
    attrs = {"energy": 8.0 * np.pi + seed, "area": 4.0 * np.pi,
             "volume": 1.2, "moment": 0.3, "eps": eps, "k": 1.0, "c0": 0.0,
             "gamma": 0.1, "nu_area": 2.5, "nu_volume": -1.5,
             "converged": True, "wall_time": 12.5, "box": BOX}
    return nodes, phi, attrs


def assert_state(ckpt, state):
    nodes, phi, attrs = state
    np.testing.assert_array_equal(ckpt.nodes, nodes)
    np.testing.assert_array_equal(ckpt.phi, phi)
    assert ckpt.attrs["energy"] == attrs["energy"]


# --------------------------------------------------------------- round trip

def test_round_trip(tmp_path):
    path = tmp_path / "state.h5"
    nodes, phi, attrs = make_state()
    attrs.update(note="ellipse", history=np.array([3.0, 2.0, 1.0]), step=7)
    extra = {"nu": np.array([1.0, -2.0, 3.0]),
             "dirichlet": nodes[:, 0] == 0.0}

    checkpoint.write(path, nodes, phi, attrs, datasets=extra)
    ckpt = checkpoint.read(path, expect_box=BOX)

    np.testing.assert_array_equal(ckpt.nodes, nodes)
    np.testing.assert_array_equal(ckpt.phi, phi)
    assert ckpt.nodes.dtype == ckpt.phi.dtype == np.float64
    for key, value in attrs.items():
        np.testing.assert_array_equal(ckpt.attrs[key], value, err_msg=key)
    assert ckpt.attrs["converged"] == 1 and type(ckpt.attrs["converged"]) is int
    assert ckpt.attrs["schema"] == "pfmembrane-checkpoint"
    assert ckpt.attrs["version"] == 1
    assert ckpt.attrs["n_procs"] == 1
    assert ckpt.box == BOX
    assert sorted(ckpt.datasets) == ["dirichlet", "nu"]
    np.testing.assert_array_equal(ckpt.datasets["nu"], extra["nu"])
    assert ckpt.datasets["dirichlet"].dtype == bool
    np.testing.assert_array_equal(ckpt.datasets["dirichlet"],
                                  extra["dirichlet"])


def test_read_checkpoint_can_be_written_again(tmp_path):
    first = tmp_path / "first.h5"
    state = make_state()
    checkpoint.write(first, *state, datasets={"nu": np.zeros(3)})
    ckpt = checkpoint.read(first)

    checkpoint.write(tmp_path / "second.h5", ckpt.nodes, ckpt.phi, ckpt.attrs,
                     datasets=ckpt.datasets)

    again = checkpoint.read(tmp_path / "second.h5")
    assert_state(again, state)
    assert again.attrs.keys() == ckpt.attrs.keys()
    assert again.datasets.keys() == {"nu"}


def test_box_tolerance(tmp_path):
    path = tmp_path / "state.h5"
    checkpoint.write(path, *make_state())
    rb, zb = BOX

    assert checkpoint.read(path, expect_box=(rb + 5e-13, zb)).box == BOX
    with pytest.raises(CheckpointError, match="differs from the expected"):
        checkpoint.read(path, expect_box=(rb, zb + 1e-10))


@pytest.mark.parametrize("change, reason", [
    (lambda s: s[2].pop("eps"), "missing attribute 'eps'"),
    (lambda s: s[2].update(converged=3), "'converged' must be 0 or 1"),
    (lambda s: s[2].update(gamma="high"), "'gamma' must be float"),
    (lambda s: s[2].update(box=(1.0,)), "'box' must be two positive"),
    (lambda s: s[2].update(schema="other"), "schema/version must be"),
    (lambda s: s[1].__setitem__(5, np.inf), "'phi' has 1 non-finite"),
    (lambda s: s.__setitem__(1, s[1][:-1]), "'phi' has shape"),
    (lambda s: s.__setitem__(0, s[0][:, :1]), "'nodes' has shape"),
    (lambda s: s[2].update(extra=object()), "'extra' of type object"),
])
def test_write_rejects_invalid_content(tmp_path, change, reason):
    path = tmp_path / "state.h5"
    state = list(make_state())
    change(state)

    with pytest.raises(CheckpointError) as info:
        checkpoint.write(path, *state)

    assert str(info.value).startswith(f"cannot write checkpoint {path}: ")
    assert reason in str(info.value)
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------- atomicity

def test_new_file_is_complete_before_it_replaces_the_old(tmp_path,
                                                         monkeypatch):
    path = tmp_path / "state.h5"
    old, new = make_state(seed=1), make_state(seed=2)
    checkpoint.write(path, *old)
    opened, replaced = [], []
    real_file, real_replace = h5py.File, os.replace

    def spy_file(name, mode="r", *args, **kwargs):
        opened.append((os.fspath(name), mode))
        return real_file(name, mode, *args, **kwargs)

    def spy_replace(src, dst):
        # The last moment before the switch: the old checkpoint must still
        # be in place, the new one already complete beside it.
        assert_state(checkpoint.read(dst), old)
        assert_state(checkpoint.read(src), new)
        replaced.append((src, dst))
        real_replace(src, dst)

    monkeypatch.setattr(h5py, "File", spy_file)
    monkeypatch.setattr(os, "replace", spy_replace)
    checkpoint.write(path, *new)

    [(src, dst)] = replaced
    assert dst == str(path)
    assert src != dst and os.path.dirname(src) == str(tmp_path)
    written = [name for name, mode in opened if mode != "r"]
    assert written == [src]
    assert_state(checkpoint.read(path), new)
    assert os.listdir(tmp_path) == ["state.h5"]


def test_failed_write_keeps_previous_file(tmp_path):
    path = tmp_path / "state.h5"
    old = make_state(seed=1)
    checkpoint.write(path, *old)
    nodes, phi, attrs = make_state(seed=2)

    # The unstorable attribute is met after the datasets are written.
    with pytest.raises(CheckpointError, match="'bad' of type dict"):
        checkpoint.write(path, nodes, phi, dict(attrs, bad={"a": 1}))

    assert_state(checkpoint.read(path), old)
    assert os.listdir(tmp_path) == ["state.h5"]


KILL_AT_FSYNC = """
import os, sys, time
import numpy as np
from pfmembrane.io import checkpoint

def stall(fd):
    print("fsync", flush=True)
    time.sleep(60)

os.fsync = stall
data = np.load(sys.argv[2])
checkpoint.write(sys.argv[1], data["nodes"], data["phi"], {k: data[k][()] for k in data.files if k not in ("nodes", "phi")})
"""


def save_state(path, state):
    nodes, phi, attrs = state
    np.savez(path, nodes=nodes, phi=phi, **attrs)


@pytest.mark.slow
def test_sigkill_before_replace_keeps_previous_file(tmp_path, child_env):
    path = tmp_path / "state.h5"
    old = make_state(seed=1)
    checkpoint.write(path, *old)
    save_state(tmp_path / "new.npz", make_state(seed=2, n_extra=20000))

    with subprocess.Popen(
            [sys.executable, "-c", KILL_AT_FSYNC, str(path),
             str(tmp_path / "new.npz")],
            stdout=subprocess.PIPE, text=True, env=child_env) as proc:
        try:
            assert proc.stdout.readline() == "fsync\n"
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait(TIMEOUT)

    assert proc.returncode == -signal.SIGKILL
    assert_state(checkpoint.read(path), old)
    leftovers = sorted(set(os.listdir(tmp_path)) - {"state.h5", "new.npz"})
    assert len(leftovers) == 1 and leftovers[0].endswith(".tmp")


WRITE_FOREVER = """
import os, sys
import numpy as np
from pfmembrane.io import checkpoint

# fsync guards against power loss, not against a killed process; skipping it
# keeps the loop writing nearly all the time, so the kill lands mid-write.
os.fsync = lambda fd: None

n = int(sys.argv[2])
nodes = np.random.default_rng(0).uniform(0.0, 1.0, (n, 2))
attrs = dict(energy=0.0, area=1.0, volume=1.0, moment=0.0, eps=0.1, k=1.0,
             c0=0.0, gamma=0.0, nu_area=0.0, nu_volume=0.0, converged=0,
             wall_time=0.0, box=(1.0, 1.0))
for step in range(10**6):
    value = (-1.0) ** step
    checkpoint.write(sys.argv[1], nodes, np.full(n, value),
                     dict(attrs, energy=value))
    print(step, flush=True)
"""


@pytest.mark.slow
@pytest.mark.parametrize("delay", [0.0, 0.05, 0.13, 0.29])
def test_sigkill_while_writing_large_files(tmp_path, delay, child_env):
    path = tmp_path / "state.h5"
    n = 500_000

    with subprocess.Popen(
            [sys.executable, "-c", WRITE_FOREVER, str(path), str(n)],
            stdout=subprocess.PIPE, text=True, env=child_env) as proc:
        try:
            assert proc.stdout.readline() == "0\n"
            time.sleep(delay)
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait(TIMEOUT)

    ckpt = checkpoint.read(path)
    assert ckpt.nodes.shape == (n, 2)
    assert ckpt.attrs["energy"] in (-1.0, 1.0)
    assert np.all(ckpt.phi == ckpt.attrs["energy"])


# --------------------------------------------------------------- bad files

def _edit(path, edit):
    with h5py.File(path, "r+") as h5:
        edit(h5)


def _replace_dataset(name, transform):
    def edit(h5):
        data = transform(h5[name][()])
        del h5[name]
        h5[name] = data
    return edit


def _truncate(path):
    os.truncate(path, os.path.getsize(path) // 2)


def _nan_phi(phi):
    phi[3] = np.nan
    return phi


BAD_FILES = {
    "missing": (lambda p: os.remove(p), "no such file"),
    "text": (lambda p: p.write_text("energy = 1\n"), "not an HDF5 file"),
    "truncated": (_truncate, "truncated or corrupt HDF5 file"),
    "foreign": (lambda p: _edit(p, lambda h5: h5.attrs.__delitem__("schema")),
                "missing attribute 'schema'"),
    "schema": (lambda p: _edit(p, lambda h5: h5.attrs.__setitem__(
        "schema", "other")), "wrong schema 'other'"),
    "version": (lambda p: _edit(p, lambda h5: h5.attrs.__setitem__(
        "version", 2)), "wrong version 2, expected 1"),
    "attribute": (lambda p: _edit(p, lambda h5: h5.attrs.__delitem__("eps")),
                  "missing attribute 'eps'"),
    "dataset": (lambda p: _edit(p, lambda h5: h5.__delitem__("phi")),
                "missing dataset 'phi'"),
    "n_mismatch": (lambda p: _edit(p, _replace_dataset(
        "phi", lambda phi: phi[:-1])), "'phi' has shape (299,) but 'nodes' "
                                       "has 300 rows"),
    "nodes_shape": (lambda p: _edit(p, _replace_dataset(
        "nodes", lambda nodes: nodes.T)), "'nodes' has shape (2, 300)"),
    "nan": (lambda p: _edit(p, _replace_dataset("phi", _nan_phi)),
            "'phi' has 1 non-finite values"),
    "box": (lambda p: _edit(p, lambda h5: h5.attrs.__setitem__(
        "box", [1.0, -2.0])), "'box' must be two positive finite numbers"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_read_rejects_bad_file(tmp_path, case):
    path = tmp_path / "state.h5"
    checkpoint.write(path, *make_state())
    damage, reason = BAD_FILES[case]
    damage(path)

    with pytest.raises(CheckpointError) as info:
        checkpoint.read(path)

    message = str(info.value)
    assert message.startswith(f"cannot read checkpoint {path}: ")
    assert reason in message
    assert "\n" not in message


def test_read_rejects_other_box(tmp_path):
    path = tmp_path / "state.h5"
    checkpoint.write(path, *make_state())

    with pytest.raises(CheckpointError, match=r"box \(Rb, Zb\) = \(1.0, 2.0\)"
                                              r" differs from the expected "
                                              r"\(1.0, 3.0\)"):
        checkpoint.read(path, expect_box=(1.0, 3.0))


def test_write_into_missing_directory(tmp_path):
    target = tmp_path / "absent" / "state.h5"

    with pytest.raises(CheckpointError, match="absent is not an existing "
                                              "directory"):
        checkpoint.write(target, *make_state())


def test_write_below_a_regular_file(tmp_path):
    (tmp_path / "file").write_text("")

    with pytest.raises(CheckpointError, match="file is not an existing "
                                              "directory"):
        checkpoint.write(tmp_path / "file" / "state.h5", *make_state())


NOBODY = 65534


@contextlib.contextmanager
def without_root():
    """As root: real and effective uid NOBODY for the block, the saved uid kept at 0 to
    come back. The checkpoint's guard is os.access, i.e. access(2), which checks the real
    uid, and root passes every permission bit; not root: nothing to do."""
    if os.geteuid() != 0:
        yield
        return
    try:
        os.setresuid(NOBODY, NOBODY, 0)
    except PermissionError:
        pytest.skip("root without CAP_SETUID cannot act as another user")
    try:
        yield
    finally:
        os.setresuid(0, 0, 0)


def test_write_into_read_only_directory(tmp_path):
    # Not under tmp_path: as root its parents are root's and 0o700, and NOBODY could not
    # reach the directory at all (the guard before, "not an existing directory", would
    # answer). The base lets others through; the locked directory lets none but its owner
    # read and no one write.
    base = Path(tempfile.mkdtemp(prefix="pfm-locked-"))
    base.chmod(0o711)
    locked = base / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    state = make_state()
    try:
        with without_root():
            assert not os.access(locked, os.W_OK)
            with pytest.raises(CheckpointError,
                               match=re.escape(f"directory {locked} is not writable")):
                checkpoint.write(locked / "state.h5", *state)
        assert os.listdir(locked) == []
    finally:
        locked.chmod(0o700)
        shutil.rmtree(base)


# --------------------------------------------------------------------- MPI

MPI_SCRIPT = """
import sys
from pathlib import Path
import numpy as np
from mpi4py import MPI
from pfmembrane.io import checkpoint

comm = MPI.COMM_WORLD
rank = comm.Get_rank()


def say(line):
    # A file per rank: mpiexec may splice the ranks' stdout mid-line.
    with open(Path(__file__).with_name(f"rank{rank}.log"), "a") as log:
        log.write(line + "\\n")


task, path = sys.argv[1], sys.argv[2]
failure = None
try:
    if task == "write":
        # Only rank 0 holds the data, as after a gather to rank 0.
        nodes = phi = attrs = None
        if rank == 0:
            data = np.load(sys.argv[3])
            nodes, phi = data["nodes"], data["phi"]
            attrs = {k: data[k][()] for k in data.files
                     if k not in ("nodes", "phi")}
        checkpoint.write(path, nodes, phi, attrs, comm=comm)
        ckpt = checkpoint.read(path, comm=comm)
        say(f"rank {rank} read {ckpt.phi.sum()!r} {ckpt.nodes.sum()!r}")
    else:
        checkpoint.read(path, comm=comm)
except checkpoint.CheckpointError as exc:
    failure = exc
    say(f"rank {rank} raised: {exc}")
# Every rank's verdict is in its log before any rank exits: once one rank exits with an
# error mpiexec tears the others down, maybe before they have written theirs. A rank left
# waiting in a collective of the checkpoint's never reaches this barrier: the run hangs
# and the test fails.
comm.Barrier()
if failure is not None:
    raise failure
say(f"rank {rank} done")
"""


@pytest.fixture
def run_mpi(mpiexec):
    """run_mpi(tmp_path, *args): run MPI_SCRIPT on two ranks; a hang fails
    the test instead of blocking it."""
    def run(tmp_path, *args):
        if shutil.which("mpiexec") is None:
            pytest.skip("mpiexec not found")
        pytest.importorskip("mpi4py")
        script = tmp_path / "mpi_script.py"
        script.write_text(textwrap.dedent(MPI_SCRIPT))
        try:
            proc = mpiexec(script, *args, timeout=TIMEOUT)
        except subprocess.TimeoutExpired:
            pytest.fail(f"mpiexec {' '.join(map(str, args))} hung")
        lines = [line for log in sorted(tmp_path.glob("rank*.log"))
                 for line in log.read_text().splitlines()]
        return proc.returncode, lines, proc.stderr
    return run


@pytest.mark.slow
@pytest.mark.mpi
def test_mpi_write_then_serial_read(tmp_path, run_mpi):
    path = tmp_path / "state.h5"
    state = make_state()
    save_state(tmp_path / "state.npz", state)

    status, lines, err = run_mpi(tmp_path, "write", path,
                                 tmp_path / "state.npz")

    assert status == 0, err
    reads = sorted(line for line in lines if " read " in line)
    assert len(reads) == 2
    assert reads[0].split()[2:] == reads[1].split()[2:]
    assert sorted(lines) == sorted(reads + ["rank 0 done", "rank 1 done"])
    ckpt = checkpoint.read(path)
    assert_state(ckpt, state)
    assert ckpt.attrs["n_procs"] == 2


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("task, reason", [
    ("read", "cannot read checkpoint {path}: no such file"),
    ("write", "cannot write checkpoint {path}: "),
])
def test_mpi_failure_raises_on_every_rank(tmp_path, task, reason, run_mpi):
    path = tmp_path / "absent" / "state.h5"
    save_state(tmp_path / "state.npz", make_state())

    status, lines, _ = run_mpi(tmp_path, task, path, tmp_path / "state.npz")

    assert status != 0
    # Each rank's own log, written before the barrier in MPI_SCRIPT: both ranks raised,
    # with one message, and neither went on.
    raised = sorted(line for line in lines if " raised: " in line)
    assert [line.split()[1] for line in raised] == ["0", "1"], lines
    messages = {line.split(" raised: ", 1)[1] for line in raised}
    assert len(messages) == 1, raised
    assert messages.pop().startswith(reason.format(path=path))
    assert sorted(lines) == raised


# -------------------------------------------------------------------- XDMF

def follow(xdmf, item):
    """Load the HDF5 dataset a DataItem refers to and check its declared
    shape and type."""
    assert item.get("Format") == "HDF"
    file_name, dataset = item.text.strip().split(":")
    with h5py.File(Path(xdmf).parent / file_name, "r") as h5:
        data = h5[dataset][()]
    dims = tuple(int(d) for d in item.get("Dimensions").split())
    assert data.shape == dims
    kind = {"Int": "i", "Float": "f"}[item.get("NumberType")]
    assert data.dtype.kind == kind
    assert data.dtype.itemsize == int(item.get("Precision"))
    return data


def parse_xdmf(xdmf):
    root = ET.parse(xdmf).getroot()
    assert root.tag == "Xdmf" and root.get("Version") == "3.0"
    [grid] = root.findall("Domain/Grid")
    topology, geometry = grid.find("Topology"), grid.find("Geometry")
    [attribute] = grid.findall("Attribute")
    assert topology.get("TopologyType") == "Triangle"
    assert geometry.get("GeometryType") == "XY"
    assert attribute.attrib == {"Name": "phi", "AttributeType": "Scalar",
                                "Center": "Node"}
    triangles = follow(xdmf, topology.find("DataItem"))
    assert int(topology.get("NumberOfElements")) == len(triangles)
    return (triangles, follow(xdmf, geometry.find("DataItem")),
            follow(xdmf, attribute.find("DataItem")))


def test_xdmf_round_trip(tmp_path):
    path = tmp_path / "state.h5"
    state = make_state()
    checkpoint.write(path, *state)

    xdmf = checkpoint.write_xdmf(path)

    assert xdmf == str(tmp_path / "state.xdmf")
    triangles, nodes, phi = parse_xdmf(xdmf)
    np.testing.assert_array_equal(nodes, state[0])
    np.testing.assert_array_equal(phi, state[1])
    # A Delaunay triangulation of nodes including the box corners tiles the
    # box: every triangle positively sized, areas summing to Rb * Zb.
    assert triangles.min() >= 0 and triangles.max() < len(nodes)
    a, b, c = (nodes[triangles[:, i]] for i in range(3))
    areas = 0.5 * np.abs(np.cross(b - a, c - a))
    assert np.all(areas > 0)
    assert np.isclose(areas.sum(), BOX[0] * BOX[1])
    ckpt = checkpoint.read(path)
    assert_state(ckpt, state)
    np.testing.assert_array_equal(ckpt.datasets["triangles"], triangles)


def test_xdmf_with_given_triangles(tmp_path):
    path = tmp_path / "state.h5"
    checkpoint.write(path, *make_state())
    checkpoint.write_xdmf(path)
    given = np.array([[0, 1, 10], [1, 11, 10]], dtype=np.int32)

    xdmf = checkpoint.write_xdmf(path, triangles=given)

    triangles, _, _ = parse_xdmf(xdmf)
    np.testing.assert_array_equal(triangles, given)
    assert sorted(os.listdir(tmp_path)) == ["state.h5", "state.xdmf"]


def test_xdmf_rejects_bad_triangles(tmp_path):
    path = tmp_path / "state.h5"
    state = make_state()
    checkpoint.write(path, *state)

    with pytest.raises(CheckpointError, match=r"outside \[0, 300\)"):
        checkpoint.write_xdmf(path, triangles=[[0, 1, 300]])

    assert "triangles" not in checkpoint.read(path).datasets
    assert sorted(os.listdir(tmp_path)) == ["state.h5"]
