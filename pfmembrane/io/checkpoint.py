"""HDF5 checkpoints of a phase-field vesicle and their XDMF description.

A checkpoint is one HDF5 file with the datasets ``nodes`` (N x 2 float64,
columns r and z) and ``phi`` (N float64) and root attributes describing the
state: ``energy``, ``area``, ``volume``, ``moment``, ``eps``, ``k``, ``c0``,
``gamma``, ``nu_area``, ``nu_volume``, ``converged`` (0/1), ``wall_time``
(seconds), ``n_procs``, ``box`` (Rb, Zb), ``schema`` =
``"pfmembrane-checkpoint"`` and ``version`` = 1.  Further attributes and
datasets are stored and returned unchanged.

Version 2 is the state of a scene with azimuthal harmonics
(`kernels.harmonics`): ``phi`` is N x nh, column j the nodal chi_j of
phi_h = sum_j r^m_j chi_j(r, z) T_j(theta), column 0 the axisymmetric part;
the root attributes ``harmonics`` (the m of each column, integers),
``harmonics_highest`` (J) and ``dihedral`` (n) say which (the layout of
`kernels.harmonics.Harmonics`: the cosines m = 0, n, ..., J n, then the sines
m = n, ..., J n if there are 2 J + 1 columns). Such a file also holds the
dataset ``phi3d``, phi_h sampled on a Cartesian grid of the box (x, y in
[-Rb, Rb], z in [0, Zb]; shape (nz, ny, nx), x varying fastest) with the
attributes ``origin`` and ``step``, each (x, y, z): phi3d[k, j, i] is phi_h at
origin + (i, j, k) * step. It is derived from ``nodes`` and ``phi`` at every
write, and `read` leaves it in the file.  An axisymmetric state is written as
version 1, so files of either kind read as they did.

Files are replaced atomically: a process killed at any moment leaves at the
target path either the previous complete file or the new complete one.
"""

import json
import os
import secrets
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import h5py
import numpy as np
import scipy.spatial

from pfmembrane.kernels.basis import locality as _locality
from pfmembrane.kernels.harmonics import Harmonics
from pfmembrane.kernels.nodes import unfold

__all__ = ["SCHEMA", "VERSION", "VERSIONS", "CheckpointError", "Checkpoint",
           "write", "read", "write_xdmf", "basis", "locality", "harmonic_set",
           "BRANCH_SCHEMA", "BRANCH_VERSION", "write_branch",
           "read_branch"]

SCHEMA = "pfmembrane-checkpoint"
VERSION = 2               # the newest; a file's is the one of its content
VERSIONS = (1, 2)         # 1: phi (N,); 2: phi (N, nh) with its harmonics

FLOAT_ATTRS = ("energy", "area", "volume", "moment", "eps", "k", "c0",
               "gamma", "nu_area", "nu_volume", "wall_time")
INT_ATTRS = ("converged", "n_procs")
REQUIRED_ATTRS = ("schema", "version", "box") + FLOAT_ATTRS + INT_ATTRS
HARMONIC_ATTRS = ("harmonics", "harmonics_highest", "dihedral")
ARRAYS = ("nodes", "phi")
SAMPLED = "phi3d"         # version 2: phi_h on a Cartesian grid, for ParaView
BOX_TOLERANCE = 1e-12


class CheckpointError(Exception):
    """A checkpoint could not be written or read; the message names the file
    and the reason."""


@dataclass
class Checkpoint:
    """The content of a checkpoint file.

    Attributes
    ----------
    nodes : ndarray, shape (N, 2)
        Node coordinates (r, z).
    phi : ndarray, shape (N,) or (N, nh)
        Phase field at the nodes; with harmonics (version 2) the nodal chi_j,
        column 0 the axisymmetric part.
    attrs : dict
        Root attributes; numbers as Python scalars, ``box`` as an array.
    datasets : dict
        Datasets other than ``nodes``, ``phi`` and ``phi3d``, by name.
    """

    nodes: np.ndarray
    phi: np.ndarray
    attrs: dict
    datasets: dict = field(default_factory=dict)

    @property
    def box(self):
        """(Rb, Zb) of the computational box."""
        rb, zb = self.attrs["box"]
        return float(rb), float(zb)

    @property
    def symmetric(self):
        """Whether the nodes fill the half box z >= Zb / 2 of a mirror-symmetric solve."""
        return bool(self.attrs.get("symmetric", 0))

    @property
    def plane(self):
        """z of the mirror plane of a half-box state, None on the full box."""
        return 0.5 * self.box[1] if self.symmetric else None

    def unfolded(self):
        """This state on the full box: a half-box solution with its mirror
        image, for plots and comparisons; a full-box one unchanged."""
        if not self.symmetric:
            return self
        nodes, phi = unfold(self.nodes, self.phi, 0.5 * self.box[1])
        return Checkpoint(nodes, phi, {**self.attrs, "symmetric": 0}, self.datasets)


def basis(attrs):
    """The max-ent basis parameters of a checkpoint's attributes (`api.Grid`'s
    keywords); files written before a parameter existed get its old value."""
    return dict(gamma=float(attrs['gamma']), cutoff=float(attrs.get('cutoff', 1e-6)),
                quad_degree=int(attrs.get('quad_degree', 4)),
                spacing_smoothing=int(attrs.get('spacing_smoothing', 0)),
                spacing_floor=float(attrs.get('spacing_floor', 0.0)))


def locality(nodes, attrs, plane=None):
    """beta_a at `nodes` of the basis of a checkpoint's attributes (`basis`),
    `plane` the mirror plane of a half box or None. Not collective."""
    b = basis(attrs)
    return _locality(nodes, b['gamma'], b['spacing_smoothing'], plane, b['spacing_floor'])


def has_sines(attrs):
    """Whether attributes `attrs` describe sines beside the cosines: more
    harmonics than the J + 1 cosines."""
    return len(attrs.get('harmonics', ())) > int(attrs.get('harmonics_highest', 0)) + 1


def harmonic_set(attrs, nh):
    """The `kernels.harmonics.Harmonics` of the nh columns of a version-2 phi
    with attributes `attrs`: its ``harmonics_highest`` J and ``dihedral`` n,
    sines beside the cosines if nh = 2 J + 1. Raises CheckpointError if an
    attribute is missing or ``harmonics`` is not their m."""
    missing = [key for key in HARMONIC_ATTRS if key not in attrs]
    if missing:
        raise CheckpointError(f"missing attribute {missing[0]!r} (phi has {nh} "
                              f"harmonics)")
    m = np.asarray(attrs["harmonics"])
    try:
        highest, dihedral = int(attrs["harmonics_highest"]), int(attrs["dihedral"])
        layout = Harmonics(highest, dihedral, sines=nh > highest + 1)
    except (TypeError, ValueError) as exc:
        raise CheckpointError(f"attributes 'harmonics_highest' and 'dihedral' "
                              f"({attrs['harmonics_highest']!r}, "
                              f"{attrs['dihedral']!r}): {_one_line(exc)}") from exc
    if m.shape != layout.m.shape or not np.array_equal(m, layout.m):
        raise CheckpointError(f"attribute 'harmonics' {m.tolist()} is not the m of "
                              f"{nh} columns of harmonics up to J = {highest} of "
                              f"dihedral order {dihedral}")
    return layout


def write(path, nodes, phi, attrs, comm=None, datasets=None, triangles=None, sample=None):
    """Write a checkpoint atomically, and its XDMF description: with
    `triangles` that of the (r, z) nodes, and always that of ``phi3d`` for a
    phi with harmonics (version 2).

    Collective.  Only the arguments given on rank 0 are used (the other ranks
    may pass None); rank 0 writes and every rank returns or raises the same
    `CheckpointError` together.

    Parameters
    ----------
    path : str or os.PathLike
        Checkpoint file to create or replace.
    nodes : array_like, shape (N, 2)
        Node coordinates (r, z).
    phi : array_like, shape (N,) or (N, nh)
        Phase field at the nodes, or its harmonics (version 2).
    attrs : dict
        Root attributes: all of the schema's (``schema`` and ``version`` may
        be omitted, a given version is replaced by the one of `phi`;
        ``n_procs`` defaults to the size of `comm`), for harmonics
        ``harmonics``, ``harmonics_highest`` and ``dihedral``, plus any
        scalars, strings or small arrays to store alongside.
    comm : mpi4py.MPI.Comm, optional
        Communicator; None for a serial call.
    datasets : dict, optional
        Extra datasets (e.g. ``nu``, ``dirichlet``) by name.
    triangles : array_like of int, shape (M, 3), optional
        Node indices of the triangles, stored as dataset ``triangles`` and
        described, with the nodes and phi, by ``<path stem>.xdmf`` (for a
        phi with harmonics, that file describes ``phi3d`` instead).
    sample : callable, optional
        For a phi with harmonics: sample(nodes, phi, attrs) -> (values (nz, ny,
        nx), origin, step), phi_h on a Cartesian grid for ``phi3d``
        (`analysis.field3d.sample`), called on rank 0.

    Raises
    ------
    CheckpointError
        Invalid content or a file system failure; `path` is then untouched.
    """
    path = os.fspath(path)

    def action():
        n_procs = 1 if comm is None else comm.Get_size()
        extra = dict(datasets or {})
        if triangles is not None:
            extra["triangles"] = _check_triangles(triangles, len(phi))
        arrays, stored_attrs = _prepare(nodes, phi, attrs, extra, n_procs)
        sampled = None
        if arrays["phi"].ndim == 2:
            if sample is None:
                raise CheckpointError("a phi with harmonics is written with its 3D sample")
            sampled = sample(arrays["nodes"], arrays["phi"], stored_attrs)
        _replace_atomically(path, lambda tmp: _fill(tmp, arrays, stored_attrs, sampled))
        if sampled is not None:
            _write_sidecar(path, _xdmf_3d_text(os.path.basename(path), *sampled[0].shape,
                                               *sampled[1:]))
        elif triangles is not None:
            _write_sidecar(path, _xdmf_text(os.path.basename(path), len(phi),
                                            len(extra["triangles"])))

    _on_root(comm, action, f"cannot write checkpoint {path}")


def read(path, comm=None, expect_box=None):
    """Read and validate a checkpoint.

    Collective.  Rank 0 reads and broadcasts, so every rank returns the same
    `Checkpoint` or raises the same `CheckpointError` together.

    Parameters
    ----------
    path : str or os.PathLike
        Checkpoint file.
    comm : mpi4py.MPI.Comm, optional
        Communicator; None for a serial call.
    expect_box : (float, float), optional
        Required (Rb, Zb), to within 1e-12.

    Returns
    -------
    Checkpoint

    Raises
    ------
    CheckpointError
        The file is missing, not HDF5, truncated, of another schema or
        version, incomplete, inconsistent, holds non-finite values, or its
        box differs from `expect_box`.
    """
    path = os.fspath(path)
    return _on_root(comm, lambda: _load(path, expect_box),
                    f"cannot read checkpoint {path}")


def write_xdmf(h5path, triangles=None):
    """Describe a checkpoint for ParaView with an XDMF 3 file beside it.

    Not collective.  The triangles are stored as dataset ``triangles`` in the
    checkpoint (replaced atomically like the checkpoint itself), so that the
    XDMF file only refers to data in the ``.h5`` file.  For a checkpoint with
    harmonics (version 2) the file describes its ``phi3d`` (see the module's
    description) rather than the (r, z) nodes.

    Parameters
    ----------
    h5path : str or os.PathLike
        Checkpoint file.
    triangles : array_like of int, shape (M, 3), optional
        Node indices of the triangles; by default the Delaunay triangulation
        of the nodes.

    Returns
    -------
    str
        Path of the XDMF file, ``<checkpoint stem>.xdmf``.

    Raises
    ------
    CheckpointError
        The checkpoint is unreadable or the triangles are invalid.
    """
    h5path = os.fspath(h5path)
    ckpt = read(h5path)
    n_nodes = len(ckpt.phi)
    name = os.path.basename(h5path)
    try:
        if triangles is None:
            triangles = scipy.spatial.Delaunay(ckpt.nodes).simplices
        triangles = _check_triangles(triangles, n_nodes)
        if ckpt.phi.ndim == 2:
            text = _xdmf_3d_text(name, *_sampled_layout(h5path))
        else:
            text = _xdmf_text(name, n_nodes, len(triangles))
        _replace_atomically(h5path,
                            lambda tmp: _add_triangles(h5path, tmp, triangles))
        return _write_sidecar(h5path, text)
    except (CheckpointError, OSError, ValueError, KeyError,
            scipy.spatial.QhullError) as exc:
        raise CheckpointError(f"cannot write XDMF for {h5path}: "
                              f"{_one_line(exc)}") from exc


def _check_triangles(triangles, n_nodes):
    triangles = np.asarray(triangles)
    if (triangles.ndim != 2 or triangles.shape[1] != 3
            or not np.issubdtype(triangles.dtype, np.integer)):
        raise CheckpointError(f"triangles must be an (M, 3) integer array, got "
                              f"{triangles.dtype} {triangles.shape}")
    if triangles.size and (triangles.min() < 0 or triangles.max() >= n_nodes):
        raise CheckpointError(f"triangle indices outside [0, {n_nodes})")
    return triangles.astype(np.int64)


def _write_sidecar(h5path, text):
    """The XDMF file beside `h5path` (`text`, of `_xdmf_text` or `_xdmf_3d_text`)."""
    xdmf = os.path.splitext(h5path)[0] + ".xdmf"
    _replace_atomically(xdmf, lambda tmp: _write_text(tmp, text))
    return xdmf


def _sampled_layout(h5path):
    """nz, ny, nx, origin and step of the ``phi3d`` of a version-2 checkpoint."""
    with h5py.File(h5path, "r") as h5:
        if SAMPLED not in h5:
            raise CheckpointError(f"no dataset {SAMPLED!r} (phi has harmonics)")
        sampled = h5[SAMPLED]
        return (*sampled.shape, np.asarray(sampled.attrs["origin"]),
                np.asarray(sampled.attrs["step"]))


def _on_root(comm, action, context):
    """Run `action` on rank 0 and hand its result or failure to every rank."""
    result = message = cause = None
    if comm is None or comm.Get_rank() == 0:
        try:
            result = action()
        # Any failure, expected or not, must reach the other ranks: they
        # would otherwise wait forever in the broadcast below.
        except Exception as exc:  # noqa: BLE001
            message, cause = f"{context}: {_one_line(exc)}", exc
    if comm is not None and comm.Get_size() > 1:
        message, result = comm.bcast((message, result), root=0)
    if message is not None:
        raise CheckpointError(message) from cause
    return result


def _one_line(exc):
    return " ".join(str(exc).split()) or type(exc).__name__


def _prepare(nodes, phi, attrs, datasets, n_procs):
    """Validate what `write` is asked to store and convert it to its
    stored types."""
    nodes = np.asarray(nodes, dtype=np.float64)
    phi = np.asarray(phi, dtype=np.float64)
    _check_arrays(nodes, phi, harmonic=True)
    arrays = {"nodes": nodes, "phi": phi}
    for name, data in (datasets or {}).items():
        if name in ARRAYS + (SAMPLED,):
            raise CheckpointError(f"extra dataset {name!r} would replace the "
                                  f"schema's one")
        arrays[name] = np.asarray(data)

    stored = dict(attrs)
    stored.setdefault("schema", SCHEMA)
    stored.setdefault("version", _version(phi))
    stored.setdefault("n_procs", n_procs)
    missing = [key for key in REQUIRED_ATTRS if key not in stored]
    if missing:
        raise CheckpointError(f"missing attribute {missing[0]!r}")
    if stored["schema"] != SCHEMA or stored["version"] not in VERSIONS:
        raise CheckpointError(f"attributes schema/version must be "
                              f"{SCHEMA!r}/{' or '.join(map(str, VERSIONS))}")
    stored["version"] = _version(phi)
    if phi.ndim == 2:
        harmonic_set(stored, phi.shape[1])
        stored["harmonics"] = np.asarray(stored["harmonics"], dtype=np.int64)
        for key in HARMONIC_ATTRS[1:]:
            stored[key] = int(stored[key])
    for keys, kind in ((FLOAT_ATTRS, float), (INT_ATTRS, int)):
        for key in keys:
            try:
                stored[key] = kind(stored[key])
            except (TypeError, ValueError) as exc:
                raise CheckpointError(f"attribute {key!r} must be "
                                      f"{kind.__name__}, got "
                                      f"{stored[key]!r}") from exc
    if stored["converged"] not in (0, 1):
        raise CheckpointError("attribute 'converged' must be 0 or 1")
    stored["box"] = np.asarray(stored["box"], dtype=np.float64)
    _check_box(stored["box"])
    return arrays, stored


def _version(phi):
    """The version of a checkpoint of `phi`: 2 with harmonics, else 1."""
    return 2 if np.ndim(phi) == 2 else 1


def _check_arrays(nodes, phi, harmonic=False):
    """`harmonic`: phi may be (N, nh), as in version 2."""
    if nodes.ndim != 2 or nodes.shape[1] != 2:
        raise CheckpointError(f"'nodes' has shape {nodes.shape}, expected "
                              f"(N, 2)")
    if phi.ndim not in ((1, 2) if harmonic else (1,)):
        raise CheckpointError(f"'phi' has shape {phi.shape}, expected "
                              f"{'(N,) or (N, nh)' if harmonic else '(N,)'}")
    if len(phi) != len(nodes):
        raise CheckpointError(f"'phi' has shape {phi.shape} but 'nodes' has "
                              f"{len(nodes)} rows")
    for name, data in (("nodes", nodes), ("phi", phi)):
        bad = np.count_nonzero(~np.isfinite(data))
        if bad:
            raise CheckpointError(f"{name!r} has {bad} non-finite values")


def _check_box(box):
    if box.shape != (2,) or not np.all(np.isfinite(box)) or np.any(box <= 0):
        raise CheckpointError(f"attribute 'box' must be two positive finite "
                              f"numbers (Rb, Zb), got {box.tolist()}")


def _set_attrs(target, attrs, where=''):
    """`attrs` as HDF5 attributes of `target` (a file or group); CheckpointError names
    the one HDF5 cannot store."""
    for key, value in attrs.items():
        try:
            target.attrs[key] = value
        except TypeError as exc:
            raise CheckpointError(f"attribute {key!r}{where} of type {type(value).__name__} "
                                  "cannot be stored in HDF5") from exc


def _fill(tmp, arrays, attrs, sampled=None):
    """The checkpoint file `tmp`; `sampled`: (values, origin, step) of
    `analysis.field3d.sample`, stored as ``phi3d``."""
    with h5py.File(tmp, "x") as h5:
        for name, data in arrays.items():
            h5.create_dataset(name, data=data)
        if sampled is not None:
            values, origin, step = sampled
            h5.create_dataset(SAMPLED, data=values)
            _set_attrs(h5[SAMPLED], dict(origin=origin, step=step), f" of {SAMPLED!r}")
        _set_attrs(h5, attrs)


def _load(path, expect_box):
    if not os.path.isfile(path):
        raise CheckpointError("no such file")
    if not h5py.is_hdf5(path):
        raise CheckpointError("not an HDF5 file")
    try:
        with h5py.File(path, "r") as h5:
            attrs = {key: _python_value(value)
                     for key, value in h5.attrs.items()}
            _check_header(attrs)
            missing = [name for name in ARRAYS if name not in h5]
            if missing:
                raise CheckpointError(f"missing dataset {missing[0]!r}")
            arrays = {name: h5[name][()] for name in h5
                      if isinstance(h5[name], h5py.Dataset) and name != SAMPLED}
    except OSError as exc:
        raise CheckpointError(f"truncated or corrupt HDF5 file "
                              f"({_one_line(exc)})") from exc
    nodes = np.asarray(arrays.pop("nodes"), dtype=np.float64)
    phi = np.asarray(arrays.pop("phi"), dtype=np.float64)
    if attrs["version"] != _version(phi):
        raise CheckpointError(f"wrong version {attrs['version']!r}, expected "
                              f"{_version(phi)!r} for a phi of shape {phi.shape}")
    _check_arrays(nodes, phi, harmonic=True)
    if phi.ndim == 2:
        harmonic_set(attrs, phi.shape[1])
    attrs["box"] = np.asarray(attrs["box"], dtype=np.float64)
    _check_box(attrs["box"])
    if expect_box is not None:
        expected = np.asarray(expect_box, dtype=np.float64)
        if np.any(np.abs(attrs["box"] - expected) > BOX_TOLERANCE):
            raise CheckpointError(f"box (Rb, Zb) = "
                                  f"{tuple(attrs['box'].tolist())} differs "
                                  f"from the expected "
                                  f"{tuple(expected.tolist())}")
    return Checkpoint(nodes, phi, attrs, arrays)


def _check_header(attrs):
    """Check the schema first so that a foreign file is reported as such
    rather than as an incomplete checkpoint."""
    for key, expected in (("schema", (SCHEMA,)), ("version", VERSIONS)):
        if key not in attrs:
            raise CheckpointError(f"missing attribute {key!r} (not a "
                                  f"{SCHEMA} file)")
        if attrs[key] not in expected:
            raise CheckpointError(f"wrong {key} {attrs[key]!r}, expected "
                                  f"{' or '.join(map(repr, expected))}")
    missing = [key for key in REQUIRED_ATTRS if key not in attrs]
    if missing:
        raise CheckpointError(f"missing attribute {missing[0]!r}")


def _python_value(value):
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.generic):
        return value.item()
    return value


def _replace_atomically(path, fill):
    """Create `path` through ``fill(tmp)`` so that it appears at once and
    complete, or not at all.

    The temporary file lives in the same directory because ``os.replace`` is
    atomic only within one file system.  Fsyncing the file before the rename
    and the directory after it keeps the new content across a power loss.
    """
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        raise CheckpointError(f"{directory} is not an existing directory")
    if not os.access(directory, os.W_OK):
        raise CheckpointError(f"directory {directory} is not writable")
    tmp = os.path.join(directory, f".{os.path.basename(path)}."
                                  f"{secrets.token_hex(8)}.tmp")
    try:
        fill(tmp)
        _fsync(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    _fsync(directory)


def _fsync(path):
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _add_triangles(h5path, tmp, triangles):
    shutil.copyfile(h5path, tmp)
    with h5py.File(tmp, "r+") as h5:
        if "triangles" in h5:
            del h5["triangles"]
        h5.create_dataset("triangles", data=triangles)


def _write_text(tmp, text):
    with open(tmp, "x", encoding="utf-8") as stream:
        stream.write(text)


def _xdmf_text(h5name, n_nodes, n_triangles):
    """The (r, z) nodes with their triangles and phi."""
    root, grid = _xdmf_grid()
    topology = ET.SubElement(grid, "Topology", TopologyType="Triangle",
                             NumberOfElements=str(n_triangles))
    _data_item(topology, f"{h5name}:/triangles", f"{n_triangles} 3", "Int")
    geometry = ET.SubElement(grid, "Geometry", GeometryType="XY")
    _data_item(geometry, f"{h5name}:/nodes", f"{n_nodes} 2", "Float")
    attribute = ET.SubElement(grid, "Attribute", Name="phi",
                              AttributeType="Scalar", Center="Node")
    _data_item(attribute, f"{h5name}:/phi", str(n_nodes), "Float")
    return _xdmf_document(root)


def _xdmf_3d_text(h5name, nz, ny, nx, origin, step):
    """``phi3d`` (nz x ny x nx, x fastest) on its 3DCoRectMesh.

    XDMF lists a CoRectMesh's dimensions slowest axis first, and VTK's
    readers (ParaView's) take its origin and spacing in that order too
    (vtkXdmf3DataSet::CopyShape reverses all three): z, y, x throughout.
    """
    root, grid = _xdmf_grid()
    dimensions = f"{nz} {ny} {nx}"
    ET.SubElement(grid, "Topology", TopologyType="3DCoRectMesh", Dimensions=dimensions)
    geometry = ET.SubElement(grid, "Geometry", GeometryType="ORIGIN_DXDYDZ")
    for name, xyz in (("Origin", origin), ("Spacing", step)):
        _data_item(geometry, " ".join(repr(float(v)) for v in xyz[::-1]), "3", "Float",
                   fmt="XML", Name=name)
    attribute = ET.SubElement(grid, "Attribute", Name="phi",
                              AttributeType="Scalar", Center="Node")
    _data_item(attribute, f"{h5name}:/{SAMPLED}", dimensions, "Float")
    return _xdmf_document(root)


def _xdmf_grid():
    root = ET.Element("Xdmf", Version="3.0")
    domain = ET.SubElement(root, "Domain")
    return root, ET.SubElement(domain, "Grid", Name="pfmembrane", GridType="Uniform")


def _xdmf_document(root):
    ET.indent(root)
    return ('<?xml version="1.0" encoding="utf-8"?>\n'
            '<!DOCTYPE Xdmf SYSTEM "Xdmf.dtd" []>\n'
            + ET.tostring(root, encoding="unicode") + "\n")


def _data_item(parent, text, dimensions, number_type, fmt="HDF", **extra):
    # The triangles, the arrays and the XML numbers are all 8-byte numbers.
    item = ET.SubElement(parent, "DataItem", **extra, Dimensions=dimensions,
                         NumberType=number_type, Precision="8", Format=fmt)
    item.text = text


# Branch files: the states of a continuation in one file.
#
# Root attributes ``schema`` = ``"pfmembrane-branch"``, ``version`` = 1, ``count``
# (the number of points) and ``attrs`` (the branch's own description, JSON); a group
# ``points/<i>`` per point, in order, with the datasets ``nodes`` and ``phi`` and the
# point's attributes (those of a checkpoint, not validated). A point on the same nodes
# as the point before holds ``nodes`` as a soft link to that point's dataset.
# Files written before the schema (an attribute ``branch``, the description with
# the table rows as ``points``; ``scene``, the first point's attributes; ``nodes``
# once; ``phi`` one row per point) are read too.

BRANCH_SCHEMA = "pfmembrane-branch"
BRANCH_VERSION = 1


def write_branch(path, points, attrs=None, comm=None):
    """Write the points of a branch, and `attrs` describing it, to one file
    atomically (the layout above).

    Collective like `write`: rank 0's arguments are written, and every rank
    returns or raises the same `CheckpointError` together.

    Parameters
    ----------
    path : str or os.PathLike
        File to create or replace (its directory must exist).
    points : sequence of Checkpoint or (nodes, phi, attrs)
        The states, in order; each point's attributes are scalars, strings
        or small arrays, as a checkpoint's.
    attrs : dict, optional
        The branch's own description: anything JSON can write (NumPy
        scalars and arrays as numbers and lists).
    comm : mpi4py.MPI.Comm, optional
        Communicator; None for a serial call.
    """
    path = os.fspath(path)

    def fill(tmp):
        with h5py.File(tmp, "x") as h5:
            h5.attrs["schema"] = BRANCH_SCHEMA
            h5.attrs["version"] = BRANCH_VERSION
            h5.attrs["count"] = len(points)
            h5.attrs["attrs"] = json.dumps(attrs or {}, default=_json_value)
            before = None
            for i, point in enumerate(points):
                if isinstance(point, Checkpoint):
                    point = (point.nodes, point.phi, point.attrs)
                nodes, phi, point_attrs = point
                nodes = np.asarray(nodes, dtype=np.float64)
                phi = np.asarray(phi, dtype=np.float64)
                _check_arrays(nodes, phi)
                group = h5.create_group(f"points/{i}")
                if before is not None and np.array_equal(nodes, before[1]):
                    group["nodes"] = h5py.SoftLink(before[0])
                else:
                    group.create_dataset("nodes", data=nodes)
                    before = (group["nodes"].name, nodes)
                group.create_dataset("phi", data=phi)
                _set_attrs(group, point_attrs, f" of point {i}")

    _on_root(comm, lambda: _replace_atomically(path, fill),
             f"cannot write branch {path}")


def read_branch(path, comm=None):
    """Read a branch file: ``(points, attrs)``, the points as `Checkpoint`s
    in order and the branch's description.

    Collective like `read`.  Refuses (`CheckpointError`) a file of another
    schema or of a version this code does not know; reads the layout
    written before the schema (see above), whose points all carry the first
    point's attributes but for their ``reduced_volume``.
    """
    path = os.fspath(path)
    return _on_root(comm, lambda: _load_branch(path), f"cannot read branch {path}")


def _json_value(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


def _load_branch(path):
    if not os.path.isfile(path):
        raise CheckpointError("no such file")
    if not h5py.is_hdf5(path):
        raise CheckpointError("not an HDF5 file")
    try:
        with h5py.File(path, "r") as h5:
            head = {key: _python_value(value) for key, value in h5.attrs.items()}
            if "schema" not in head and {"branch", "scene"} <= set(head):
                return _old_branch(h5, head)
            if head.get("schema") != BRANCH_SCHEMA:
                raise CheckpointError(f"schema {head.get('schema')!r}, not a "
                                      f"{BRANCH_SCHEMA} file")
            if head.get("version") != BRANCH_VERSION:
                raise CheckpointError(f"{BRANCH_SCHEMA} version "
                                      f"{head.get('version')!r} unknown: this "
                                      f"pfmembrane reads version {BRANCH_VERSION}")
            points, shared = [], {}
            for i in range(int(head["count"])):
                group = h5[f"points/{i}"]
                link = group.get("nodes", getlink=True)
                name = link.path if isinstance(link, h5py.SoftLink) else group["nodes"].name
                if name not in shared:
                    shared[name] = np.asarray(h5[name][()], dtype=np.float64)
                attrs = {key: _python_value(value) for key, value in group.attrs.items()}
                points.append(Checkpoint(shared[name], np.asarray(group["phi"][()],
                                                                  dtype=np.float64), attrs))
            return points, json.loads(head["attrs"])
    except (OSError, KeyError) as exc:
        raise CheckpointError(f"truncated or corrupt branch file "
                              f"({_one_line(exc)})") from exc


def _old_branch(h5, head):
    """A branch file of the layout before the schema."""
    about, scene = json.loads(head["branch"]), json.loads(head["scene"])
    nodes = np.asarray(h5["nodes"][()], dtype=np.float64)
    points = [Checkpoint(nodes, np.asarray(phi, dtype=np.float64),
                         dict(scene, reduced_volume=p["v"]))
              for phi, p in zip(h5["phi"][()], about["points"])]
    return points, about
