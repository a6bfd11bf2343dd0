"""A solved (or stopped) state: its nodes and phi, typed fields for what users
read, the checkpoint attributes for the rest; reading and writing it."""
import math
from dataclasses import dataclass, field

import numpy as np

from pfmembrane.io import checkpoint
from pfmembrane.kernels.initial import reduced_volume
from pfmembrane.scene import Scene


def multiplier_names(attrs):
    """The attribute names of the multipliers (L = E - nu . (c - c0)) of a
    result with attributes `attrs`, one per constraint: nu_A, nu_V, nu_M on a
    full box (the moment along the axis), nu_X with the harmonic m = 1 (the
    moment across it, `parallel.assembly`), nu_phase with sines (the phase
    condition, `parallel.harmonic`)."""
    names = ['nu_area', 'nu_volume']
    if not attrs.get('symmetric', 0):
        names.append('nu_moment')
    highest = int(attrs.get('harmonics_highest', 0))
    if highest >= 1 and int(attrs.get('dihedral', 1)) == 1:
        names.append('nu_moment_x')
    if checkpoint.has_sines(attrs):
        names.append('nu_phase')
    return names


@dataclass
class Result:
    """A solved (or stopped) state: nodes and nodal phi on every rank, and the
    checkpoint attributes (`io.checkpoint`): energy, area, volume, moment, the
    multipliers, eps, the scene, converged, times. With azimuthal harmonics phi
    is (nodes x nh), the nodal chi_j of the m in attrs['harmonics'] (column 0
    the axisymmetric part). `grid` is the grid it was solved on (None for a
    result read from a file); `unused_options` the options given to its solve
    that nothing used."""
    nodes: np.ndarray
    phi: np.ndarray
    attrs: dict
    grid: object = None
    message: str = ''
    status: int = 0
    path: str = ''
    datasets: dict = field(default_factory=dict)
    unused_options: list = field(default_factory=list)

    @property
    def energy(self):
        return float(self.attrs['energy'])

    @property
    def eps(self):
        return float(self.attrs['eps'])

    @property
    def converged(self):
        return bool(self.attrs['converged'])

    @property
    def nu(self):
        """Multipliers (nu_A, nu_V[, nu_M][, nu_X]): L = E - nu . (c - c0)."""
        return np.array([float(self.attrs.get(k, 0.0)) for k in multiplier_names(self.attrs)])

    @property
    def level_set_energy(self):
        """The Canham-Helfrich energy of phi_h = 0, the sharp-limit estimate
        (NaN where undefined or not computed: `solve(..., checks=True)`)."""
        return float(self.attrs.get('level_set_energy', math.nan))

    @property
    def level_set_reduced_volume(self):
        """The reduced volume 6 sqrt(pi) V / A^1.5 of phi_h = 0, from the
        area and volume the checks measure of a torus and of any surface with
        harmonics (NaN where they did not: no checks, or one sphere's
        axisymmetric checks, which compare it with the sharp shape instead)."""
        a = self.attrs
        if 'level_set_area' not in a:
            return math.nan
        return float(reduced_volume(a['level_set_area'], a['level_set_volume']))

    @property
    def topology(self):
        """What phi_h = 0 is ('1 sphere', '2 spheres', '1 torus', ...; '' unchecked)."""
        return str(self.attrs.get('topology', ''))

    @property
    def components(self):
        """The number of components of phi_h = 0 (0 unchecked)."""
        return int(self.attrs.get('components', 0))

    @property
    def genus(self):
        """The number of tori among them (0 unchecked)."""
        return int(self.attrs.get('genus', 0))

    @property
    def index(self):
        """The stability index per azimuthal mode m (`stability`; empty before)."""
        return [int(i) for i in self.attrs.get('index_m', ())]

    @property
    def times(self):
        """The time split in seconds (NaN where not measured): `wall`, `setup`,
        `adapt`, `stage1`, `stage2`, `assembly`, `linear`, `modes`."""
        keys = {'wall': 'wall_time', **{k: 'time_' + k for k in (
            'setup', 'adapt', 'stage1', 'stage2', 'assembly', 'linear', 'modes')}}
        return {k: float(self.attrs.get(key, math.nan)) for k, key in keys.items()}

    @property
    def scene(self):
        return Scene.of(self.attrs)

    @property
    def basis(self):
        """The basis parameters it was solved with (`Grid`'s keywords)."""
        return checkpoint.basis(self.attrs)

    def locality(self, plane=None):
        """beta_a of its basis at its nodes (`plane`: the mirror plane of a half box):
        its grid's, when it has its grid."""
        if self.grid is not None and self.grid.discrete.plane == plane:
            return self.grid.discrete.beta
        return checkpoint.locality(self.nodes, self.attrs, plane)

    def checkpoint(self):
        return checkpoint.Checkpoint(self.nodes, self.phi, self.attrs, self.datasets)

    def unfolded(self):
        """This state on the full box: a half-box result with its mirror image, on its
        nodes and their images (a start for a full-box solve on those nodes, where the
        up-down symmetry is free to break: an up-down symmetric grid keeps a pitchfork a
        pitchfork); a full-box one unchanged."""
        if not self.attrs.get('symmetric', 0):
            return self
        ck = self.checkpoint().unfolded()
        return Result(ck.nodes, ck.phi, ck.attrs, message=self.message, status=self.status)

    def save(self, path):
        """Write the checkpoint and its `.xdmf` beside it, atomically: with
        harmonics, phi_h sampled in 3D and its description (`io.checkpoint`).

        Collective on the grid's communicator (serial for a result read back).
        """
        comm = self.grid.comm.tompi4py() if self.grid is not None else None
        triangles = (self.grid.discrete.triangles if self.grid is not None
                     else self.datasets.get('triangles'))
        sample = None
        if np.ndim(self.phi) == 2:
            from pfmembrane.analysis import field3d
            # the grid's locality, if it has it; without, rank 0 computes it
            beta = self.locality(self.checkpoint().plane) if self.grid is not None else None
            sample = lambda nodes, phi, attrs: field3d.sample(nodes, phi, attrs, beta)  # noqa: E731
        checkpoint.write(path, self.nodes, self.phi, self.attrs, comm=comm,
                         datasets={k: v for k, v in self.datasets.items() if k != 'triangles'},
                         triangles=triangles, sample=sample)
        self.path = str(path)
        return self


def read(path, comm=None, expect_box=None):
    """The result stored in a checkpoint; collective when `comm` (mpi4py or
    PETSc) is given. `expect_box`: (Rb, Zb) it must have."""
    if comm is not None and hasattr(comm, 'tompi4py'):
        comm = comm.tompi4py()
    ck = checkpoint.read(path, comm, expect_box=expect_box)
    return Result(ck.nodes, ck.phi, ck.attrs, path=str(path), datasets=ck.datasets)


def save_branch(path, results, comm=None, attrs=None):
    """Write the points of a branch (`results`, in order: a continuation's, say)
    and `attrs`, a JSON-able description of the branch as a whole, to one
    versioned file (`io.checkpoint.write_branch`), atomically; its directory
    must exist. Collective when `comm` (mpi4py or PETSc) is given: rank 0's
    arguments are written and every rank returns or raises together."""
    if comm is not None and hasattr(comm, 'tompi4py'):
        comm = comm.tompi4py()
    checkpoint.write_branch(path, [(r.nodes, r.phi, r.attrs) for r in results], attrs, comm)


def read_branch(path, comm=None):
    """(results, attrs): the points of a branch file as `Result`s (without their
    grid), in order, and the branch's description; collective when `comm` is
    given. A file of an unknown version is refused (`io.checkpoint.CheckpointError`);
    one of the layout before the versioned one is read."""
    if comm is not None and hasattr(comm, 'tompi4py'):
        comm = comm.tompi4py()
    points, attrs = checkpoint.read_branch(path, comm)
    return [Result(p.nodes, p.phi, p.attrs) for p in points], attrs
