"""Checkpoints of a state with azimuthal harmonics (pfmembrane.io.checkpoint,
version 2): phi (N, nh) and its attributes round trip bit for bit, an
axisymmetric file reads as before, phi3d and its XDMF 3DCoRectMesh place each
value where phi_h has it, and the files are replaced atomically.

No solve: the state is the harmonics (m = 0, 2, 4) of a tanh ellipsoid, long
along x, on a uniform node set."""

import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from types import SimpleNamespace

import h5py
import numpy as np
import pytest

from pfmembrane.analysis import field3d
from pfmembrane.analysis.field3d import Harmonic3D
from pfmembrane.io import checkpoint
from pfmembrane.io.checkpoint import CheckpointError
from pfmembrane.kernels import initial
from pfmembrane.kernels.basis import locality
from pfmembrane.kernels.harmonics import Harmonics
from pfmembrane.kernels.nodes import uniform
from pfmembrane.result import Result, read
from pfmembrane.starts import start_phi

BOX = (0.8, 1.2)           # Rb != Zb: an x-z swap moves the box
EPS = 0.08               # coarse, for a fast raster and sample (a write ~0.1 s)
AXES = (0.5, 0.3, 0.3)     # semi-axes along x, y, z: cos 2 theta tells x from y
GAMMA = 0.8
TIMEOUT = 60


def harmonic_state(plane=None, n=1500, seed=0):
    """Nodes, nodal chi_j (N x 3, m = 0, 2, 4) of the ellipsoid about z = Zb / 2
    and a complete set of attributes (those of a scene, for `Result.scene`)."""
    xy = uniform(BOX, n, half=plane is not None)
    h = Harmonics(2, 2)
    phi = initial.harmonic_coefficients(
        xy - [0.0, 0.5 * BOX[1]], lambda p: initial.ellipsoid_phi(p, AXES, EPS), h, 0.02)
    attrs = {"energy": 8.0 * np.pi + seed, "area": 1.5, "volume": 0.3, "moment": 0.0,
             "eps": EPS, "k": 1.0, "c0": 0.0, "gamma": GAMMA, "nu_area": 2.5,
             "nu_volume": -1.5, "converged": 1, "wall_time": 1.5, "box": BOX,
             "cutoff": 1e-6, "symmetric": int(plane is not None), "reduced_volume": 0.8,
             "radius": 0.3, "branch": "prolate", "harmonics": h.m,
             "harmonics_highest": 2, "dihedral": 2}
    return xy, phi + 1e-3 * seed, attrs


def axisymmetric_state():
    xy = uniform(BOX, 400)
    phi = np.tanh((0.3 - np.hypot(xy[:, 0], xy[:, 1] - 0.6)) / (np.sqrt(2) * EPS))
    _, _, attrs = harmonic_state(n=50)
    for key in checkpoint.HARMONIC_ATTRS:
        attrs.pop(key)
    return xy, phi, attrs


def field_of(state, plane=None):
    """phi_h of a state, built as `field3d.sample` is asked to build it."""
    xy, phi, attrs = state
    return Harmonic3D.of(xy, phi, attrs["harmonics"], np.zeros(3, bool), BOX, EPS,
                         locality(xy, GAMMA, 0, plane), 1e-6, plane)


@pytest.fixture(scope="module")
def state():
    return harmonic_state()


def assert_same(ckpt, state):
    nodes, phi, attrs = state
    np.testing.assert_array_equal(ckpt.nodes, nodes)
    np.testing.assert_array_equal(ckpt.phi, phi)
    assert ckpt.attrs["energy"] == attrs["energy"]


# ------------------------------------------------------------- round trip

def test_round_trip_bit_for_bit(tmp_path, state):
    nodes, phi, attrs = state
    path = tmp_path / "h.h5"
    checkpoint.write(path, nodes, phi, attrs, datasets={"nu": np.array([1.0, 2.0])},
                     sample=field3d.sample)

    ckpt = checkpoint.read(path, expect_box=BOX)

    assert ckpt.phi.shape == (len(nodes), 3) and ckpt.phi.dtype == np.float64
    assert ckpt.phi.tobytes() == np.asarray(phi, dtype=np.float64).tobytes()
    assert ckpt.nodes.tobytes() == nodes.tobytes()
    for key, value in attrs.items():
        np.testing.assert_array_equal(ckpt.attrs[key], value, err_msg=key)
    assert ckpt.attrs["version"] == 2 == checkpoint.VERSION
    assert ckpt.attrs["harmonics"].dtype.kind == "i"
    assert type(ckpt.attrs["harmonics_highest"]) is int is type(ckpt.attrs["dihedral"])
    assert sorted(ckpt.datasets) == ["nu"]          # phi3d stays in the file
    with h5py.File(path, "r") as h5:
        assert h5["phi"].shape == (len(nodes), 3)
        assert sorted(h5) == ["nodes", "nu", "phi", "phi3d"]


def test_a_result_read_back_saves_and_restarts_as_it_was(tmp_path, state):
    nodes, phi, attrs = state
    first, second = tmp_path / "first.h5", tmp_path / "second.h5"
    Result(nodes, phi, dict(attrs)).save(first)

    res = read(first)
    res.save(second)                                  # no grid: rank 0 gets beta itself

    again = read(second)
    assert again.phi.tobytes() == res.phi.tobytes() == phi.tobytes()
    assert again.attrs.keys() == res.attrs.keys()
    with h5py.File(first, "r") as a, h5py.File(second, "r") as b:
        np.testing.assert_array_equal(a["phi3d"][()], b["phi3d"][()])
    # a restart on the same nodes (pf.solve's start_phi) takes the harmonics as they are
    scene = again.scene
    assert (scene.harmonics, scene.dihedral) == (2, 2)
    np.testing.assert_array_equal(scene.harmonic_set.m, attrs["harmonics"])
    grid = SimpleNamespace(nodes=nodes, n_nodes=len(nodes), symmetric=False,
                           transferred=None, plane=None)
    start, nu, converged = start_phi(scene, grid, EPS, again)
    assert start.shape == (len(nodes), 3)
    np.testing.assert_array_equal(start, phi)
    np.testing.assert_array_equal(nu, [2.5, -1.5, 0.0])


@pytest.mark.parametrize("change, reason", [
    (lambda s: s[2].pop("dihedral"), "missing attribute 'dihedral'"),
    (lambda s: s[2].update(harmonics=np.array([0, 1, 2])), "is not the m of 3 columns"),
    (lambda s: s[2].update(harmonics_highest=3), "is not the m of 3 columns"),
    (lambda s: s[2].update(version=3), "schema/version must be"),
    (lambda s: s.__setitem__(1, s[1][:, :, None]), "expected (N,) or (N, nh)"),
])
def test_write_rejects_inconsistent_harmonics(tmp_path, state, change, reason):
    state = [state[0], state[1].copy(), dict(state[2])]
    change(state)
    with pytest.raises(CheckpointError) as info:
        checkpoint.write(tmp_path / "h.h5", *state, sample=field3d.sample)
    assert reason in str(info.value)
    assert os.listdir(tmp_path) == []


def test_a_given_version_follows_the_content(tmp_path, state):
    nodes, phi, attrs = state
    checkpoint.write(tmp_path / "h.h5", nodes, phi, dict(attrs, version=1),
                     sample=field3d.sample)
    checkpoint.write(tmp_path / "a.h5", nodes, phi[:, 0], dict(attrs, version=2))
    assert checkpoint.read(tmp_path / "h.h5").attrs["version"] == 2
    assert checkpoint.read(tmp_path / "a.h5").attrs["version"] == 1


@pytest.mark.parametrize("edit, reason", [
    (lambda h5: h5.attrs.__setitem__("version", 1), "wrong version 1, expected 2"),
    (lambda h5: h5.attrs.__setitem__("version", 3), "wrong version 3, expected 1 or 2"),
    (lambda h5: h5.attrs.__delitem__("harmonics"), "missing attribute 'harmonics'"),
    (lambda h5: h5.attrs.__setitem__("harmonics", [0, 2]), "is not the m of 3 columns"),
])
def test_read_rejects_inconsistent_files(tmp_path, state, edit, reason):
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)
    with h5py.File(path, "r+") as h5:
        edit(h5)
    with pytest.raises(CheckpointError, match="cannot read checkpoint") as info:
        checkpoint.read(path)
    assert reason in str(info.value)


def test_branch_files_refuse_harmonics_cleanly(tmp_path, state):
    with pytest.raises(CheckpointError, match=r"'phi' has shape \(\d+, 3\), expected \(N,\)"):
        checkpoint.write_branch(tmp_path / "b.h5", [state])


# ------------------------------------------------------------- axisymmetric

def test_axisymmetric_checkpoints_are_read_and_written_as_before(tmp_path):
    nodes, phi, attrs = axisymmetric_state()
    path = tmp_path / "a.h5"
    checkpoint.write(path, nodes, phi, attrs, triangles=[[0, 1, 2]], sample=field3d.sample)

    ckpt = checkpoint.read(path)

    assert ckpt.attrs["version"] == 1 and ckpt.phi.shape == (len(nodes),)
    np.testing.assert_array_equal(ckpt.phi, phi)
    assert "harmonics" not in ckpt.attrs and Result(ckpt.nodes, ckpt.phi, ckpt.attrs).scene \
        .harmonics == 0
    with h5py.File(path, "r") as h5:
        assert sorted(h5) == ["nodes", "phi", "triangles"]
    xdmf = ET.parse(tmp_path / "a.xdmf").getroot()
    assert xdmf.find("Domain/Grid/Topology").get("TopologyType") == "Triangle"
    assert xdmf.find("Domain/Grid/Attribute/DataItem").text == "a.h5:/phi"


def test_a_file_written_as_version_1_before_is_read_unchanged(tmp_path):
    """A file as the code before version 2 wrote it, made with h5py alone."""
    nodes, phi, attrs = axisymmetric_state()
    path = tmp_path / "old.h5"
    with h5py.File(path, "w") as h5:
        h5["nodes"], h5["phi"] = nodes, phi
        for key, value in dict(attrs, schema="pfmembrane-checkpoint", version=1,
                               n_procs=1).items():
            h5.attrs[key] = value
    ckpt = checkpoint.read(path)
    assert ckpt.attrs["version"] == 1
    assert ckpt.phi.tobytes() == phi.tobytes() and ckpt.datasets == {}


# ------------------------------------------------------------- phi3d, XDMF

def parse_3d(xdmf):
    """(dims, origin, spacing, reference) as the XDMF lists them, slowest axis first."""
    grid = ET.parse(xdmf).getroot().find("Domain/Grid")
    topology, geometry = grid.find("Topology"), grid.find("Geometry")
    assert topology.get("TopologyType") == "3DCoRectMesh"
    assert geometry.get("GeometryType") == "ORIGIN_DXDYDZ"
    items = {item.get("Name"): item for item in geometry.findall("DataItem")}
    origin, spacing = (np.array(items[k].text.split(), dtype=float) for k in ("Origin", "Spacing"))
    attribute = grid.find("Attribute")
    assert (attribute.get("Name"), attribute.get("Center")) == ("phi", "Node")
    item = attribute.find("DataItem")
    dims = tuple(int(d) for d in topology.get("Dimensions").split())
    assert tuple(int(d) for d in item.get("Dimensions").split()) == dims
    assert item.get("Format") == "HDF" and item.get("Precision") == "8"
    return dims, origin, spacing, item.text


def vtk_points(dims, origin, spacing, ids):
    """The coordinates VTK's XDMF readers give point `ids` of a 3DCoRectMesh: the
    dimensions, origin and spacing listed z, y, x, and x varying fastest."""
    nx, ny, _ = dims[::-1]
    i, j, k = ids % nx, (ids // nx) % ny, ids // (nx * ny)
    return origin[::-1] + np.column_stack([i, j, k]) * spacing[::-1]


@pytest.mark.parametrize("plane", [None, 0.5 * BOX[1]], ids=["full", "half"])
def test_phi3d_is_phi_h_where_the_xdmf_puts_it(tmp_path, plane):
    state = harmonic_state(plane)
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)

    dims, origin, spacing, reference = parse_3d(tmp_path / "h.xdmf")
    with h5py.File(path, "r") as h5:
        data = h5["phi3d"]
        values, h5_origin, step = data[()], data.attrs["origin"], data.attrs["step"]

    assert reference == "h.h5:/phi3d"
    assert dims == values.shape                                   # nz, ny, nx
    np.testing.assert_array_equal(origin[::-1], h5_origin)
    np.testing.assert_array_equal(spacing[::-1], step)
    np.testing.assert_allclose(h5_origin, [-BOX[0], -BOX[0], 0.0])
    np.testing.assert_allclose(h5_origin + step * (np.array(dims[::-1]) - 1),
                               [BOX[0], BOX[0], BOX[1]])     # the whole box, z mirrored
    assert np.all(step <= field3d.SAMPLE_STEP * EPS + 1e-15)
    assert np.all(step > 0.9 * field3d.SAMPLE_STEP * EPS)
    # point ids as a reader numbers the flat (C-ordered) data
    ids = np.random.default_rng(1).integers(0, values.size, 40)
    points = vtk_points(dims, origin, spacing, ids)
    np.testing.assert_allclose(values.ravel()[ids], field_of(state, plane)(points)[0],
                               rtol=0, atol=1e-12)
    # and against the ellipsoid itself, so that no common transposition passes: inside
    # along x at 0.4, outside along y and z at 0.4 (|phi| ~ 1 at 2 eps from the surface)
    zc = 0.5 * BOX[1]
    everywhere = vtk_points(dims, origin, spacing, np.arange(values.size))
    for xyz, sign in (((0.4, 0, zc), 1), ((0, 0.4, zc), -1), ((0, 0, zc + 0.4), -1),
                      ((0, 0, zc - 0.4), -1), ((-0.4, 0, zc), 1), ((0, 0, zc), 1)):
        nearest = np.argmin(np.linalg.norm(everywhere - xyz, axis=1))
        assert np.sign(values.ravel()[nearest]) == sign, xyz


def test_the_sample_is_capped(tmp_path, state, monkeypatch):
    monkeypatch.setattr(field3d, "SAMPLE_POINTS", 20_000)
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)
    with h5py.File(path, "r") as h5:
        size, step = h5["phi3d"].size, h5["phi3d"].attrs["step"]
    assert 10_000 < size <= 20_000
    assert np.all(step > field3d.SAMPLE_STEP * EPS)
    dims, _, spacing, _ = parse_3d(tmp_path / "h.xdmf")
    assert np.prod(dims) == size
    np.testing.assert_array_equal(spacing[::-1], step)


def test_write_xdmf_of_a_harmonic_checkpoint(tmp_path, state):
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)
    os.remove(tmp_path / "h.xdmf")

    xdmf = checkpoint.write_xdmf(path)

    assert xdmf == str(tmp_path / "h.xdmf")
    dims, *_ = parse_3d(xdmf)
    with h5py.File(path, "r") as h5:
        assert h5["phi3d"].shape == dims and "triangles" in h5
    assert_same(checkpoint.read(path), state)


# ------------------------------------------------------------- atomicity

def test_new_files_are_complete_before_they_replace_the_old(tmp_path, monkeypatch):
    path, xdmf = tmp_path / "h.h5", str(tmp_path / "h.xdmf")
    old, new = harmonic_state(seed=1), harmonic_state(seed=2)
    checkpoint.write(path, *old, sample=field3d.sample)
    opened, replaced = [], []
    real_file, real_replace = h5py.File, os.replace

    def spy_file(name, mode="r", *args, **kwargs):
        opened.append((os.fspath(name), mode))
        return real_file(name, mode, *args, **kwargs)

    def spy_replace(src, dst):
        # The last moment before each switch: the old file still in place, the
        # new one complete beside it; the XDMF last, when its .h5 is in place.
        if dst == str(path):
            assert_same(checkpoint.read(dst), old)
            assert_same(checkpoint.read(src), new)
            with real_file(src, "r") as h5:
                assert h5["phi3d"].ndim == 3
        else:
            assert dst == xdmf and replaced[-1][1] == str(path)
            assert_same(checkpoint.read(path), new)
            assert parse_3d(src)[3] == "h.h5:/phi3d"
        replaced.append((src, dst))
        real_replace(src, dst)

    monkeypatch.setattr(h5py, "File", spy_file)
    monkeypatch.setattr(os, "replace", spy_replace)
    checkpoint.write(path, *new, sample=field3d.sample)

    assert [dst for _, dst in replaced] == [str(path), xdmf]
    assert all(os.path.dirname(src) == str(tmp_path) for src, _ in replaced)
    written = [name for name, mode in opened if mode != "r"]
    assert written == [replaced[0][0]]
    assert_same(checkpoint.read(path), new)
    assert sorted(os.listdir(tmp_path)) == ["h.h5", "h.xdmf"]


def test_failed_write_keeps_previous_files(tmp_path, state):
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)
    before = (tmp_path / "h.xdmf").read_bytes()
    nodes, phi, attrs = harmonic_state(seed=2)

    # The unstorable attribute is met after the datasets, phi3d too, are written.
    with pytest.raises(CheckpointError, match="'bad' of type dict"):
        checkpoint.write(path, nodes, phi, dict(attrs, bad={"a": 1}), sample=field3d.sample)

    assert_same(checkpoint.read(path), state)
    assert (tmp_path / "h.xdmf").read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["h.h5", "h.xdmf"]


KILL_AT_FSYNC = """
import os, sys, time
import numpy as np
from pfmembrane.analysis import field3d
from pfmembrane.io import checkpoint

def stall(fd):
    print("fsync", flush=True)
    time.sleep(60)

data = np.load(sys.argv[2])
attrs = {k: data[k].item() if data[k].ndim == 0 else data[k] for k in data.files
         if k not in ("nodes", "phi")}
os.fsync = stall
checkpoint.write(sys.argv[1], data["nodes"], data["phi"], attrs, sample=field3d.sample)
"""


@pytest.mark.slow
def test_sigkill_before_replace_keeps_previous_files(tmp_path, state, child_env):
    path = tmp_path / "h.h5"
    checkpoint.write(path, *state, sample=field3d.sample)
    before = (tmp_path / "h.xdmf").read_bytes()
    nodes, phi, attrs = harmonic_state(seed=2)
    np.savez(tmp_path / "new.npz", nodes=nodes, phi=phi, **attrs)

    with subprocess.Popen([sys.executable, "-c", KILL_AT_FSYNC, str(path),
                           str(tmp_path / "new.npz")],
                          stdout=subprocess.PIPE, text=True, env=child_env) as proc:
        try:
            assert proc.stdout.readline() == "fsync\n"
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait(TIMEOUT)

    assert proc.returncode == -signal.SIGKILL
    assert_same(checkpoint.read(path), state)
    assert (tmp_path / "h.xdmf").read_bytes() == before
    leftovers = sorted(set(os.listdir(tmp_path)) - {"h.h5", "h.xdmf", "new.npz"})
    assert len(leftovers) == 1 and leftovers[0].endswith(".tmp")

