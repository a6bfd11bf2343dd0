"""A grid: nodes of a scene's box with their max-ent basis, partition and
operators, built once and reused by every solve on it; CVT-adapted grids."""
import time

import numpy as np

from pfmembrane.io.options import Params
from pfmembrane.kernels import nodes as nodesets
from pfmembrane.kernels.nodes import spacing_peak
from pfmembrane.parallel import petsc

# eps >= RESOLUTION * h_min, h_min the left peak of the mean-neighbour-distance
# distribution: calibrated on the paper's Tables 1-5 (admitted eps/h = 1.67-1.76,
# refused 1.18-1.25).
RESOLUTION = 1.5


class Grid:
    """Nodes of a scene's box with their max-ent basis, partition, operators
    and Hessian products, built once and reused by every solve on it.

    Collective on `comm`. `gamma` is the max-ent locality (beta_a = gamma /
    h_a^2), `cutoff` the support cut-off, `quad_degree` the Gauss rule on the
    Delaunay triangles, `spacing_smoothing` the passes over h_a behind beta_a,
    `spacing_floor` the quantile Q of the smoothed h_a below which beta_a stays
    gamma / h_Q^2 (0: none; graded grids, `basis.spacing_and_locality`),
    `partition` the split of the nodes among the ranks (`parallel.partition`).
    """

    def __init__(self, scene, nodes, gamma=Params.gamma, cutoff=Params.cutoff,
                 quad_degree=Params.quad_degree, spacing_smoothing=Params.spacing_smoothing,
                 spacing_floor=Params.spacing_floor, partition=Params.partition, comm=None):
        from pfmembrane.parallel.discretization import Discretization
        PETSc = petsc.start()
        if scene.box == 'auto':
            raise ValueError("the scene's box is 'auto': size it first (Scene.sized(eps))")
        self.comm = petsc.comm(comm)
        self.box, self.symmetric, self.plane = scene.box, scene.symmetric, scene.plane
        self.params = dict(gamma=gamma, cutoff=cutoff, quad_degree=quad_degree,
                           spacing_smoothing=spacing_smoothing, spacing_floor=spacing_floor,
                           partition=partition)
        self.adapt_info, self.transferred = None, None
        t0 = time.perf_counter()
        stage = PETSc.Log.Stage('pfBasis')
        stage.push()
        try:
            self.discrete = Discretization(self.comm, np.asarray(nodes, dtype=float), scene.box,
                                           gamma, cutoff, quad_degree, spacing_smoothing,
                                           scene.plane, partition, spacing_floor)
            self.discrete.gram  # stage 2 always needs the Hessian
        finally:
            stage.pop()
        self.setup_time = time.perf_counter() - t0
        self.setup_pending = True  # the first solve reports the set-up time
        self.eps_min = RESOLUTION * spacing_peak(self.discrete.h)

    @classmethod
    def uniform(cls, scene, nodes=Params.nodes, **kwargs):
        """A near-hexagonal grid of about `nodes` nodes of the full box (its
        half with the scene's mirror plane), nodes on every edge."""
        return cls(scene, nodesets.uniform(scene.box, nodes, half=scene.symmetric), **kwargs)

    @classmethod
    def of(cls, result, comm=None, **kwargs):
        """The grid of a result's nodes, with its basis parameters unless given."""
        return cls(result.scene, result.nodes, **{**result.basis, **kwargs}, comm=comm)

    @property
    def nodes(self):
        return self.discrete.nodes

    @property
    def n_nodes(self):
        return len(self.discrete.nodes)

    @property
    def spacing(self):
        """s_a of the locality beta_a = gamma / s_a^2: the smoothed nodal
        spacing, held at its floor quantile where the grid has one."""
        return np.sqrt(self.params['gamma'] / self.discrete.beta)

    def adapt_summary(self):
        """One line on the CVT relocation that made this grid ('' for a grid
        not made by `adapt`)."""
        info = self.adapt_info
        if not info:
            return ''
        band = f" band={info['band']:g}" if info['band'] else ''
        return (f"adapt: CVT f={info['f']:g}{band} of {info['of']}: {info['iterations']} Lloyd "
                f"steps (movement {info['movement']:.1e}), h_min {info['h_min'][0]:.4g} -> "
                f"{info['h_min'][1]:.4g}, raster {info['raster'][1]}x{info['raster'][0]}, "
                f"{info['time']:.2f} s")

    def fits(self, scene):
        """Whether `scene` can be solved on this grid: same box and symmetry."""
        return (scene.box != 'auto' and np.allclose(scene.box, self.box, rtol=0, atol=1e-12)
                and scene.symmetric == self.symmetric)

    def __repr__(self):
        d = self.discrete
        return (f"Grid({self.n_nodes} nodes, {d.layout.nglobal} free, {d.nquad} quadrature "
                f"points, gamma {self.params['gamma']:g}, eps_min {self.eps_min:.4g})")


def adapt(result, f, comm=None, along=(), band=0.0, **grid_params):
    """A grid of as many nodes as `result`'s, relocated by CVT for the density
    1 + f |grad phi_h| (paper Section 4.2), with its basis parameters unless
    given. A solve on it started from `result` uses phi_h transferred to the
    new nodes. `along`: results on `result`'s nodes (the points of a branch)
    whose interfaces the grid follows too, by the largest |grad phi_h| of
    them all. `band` > 0: |grad phi_h| replaced by its largest value within
    that distance, so the nodes are evenly spaced across the interfaces and
    graded only where phi_h is near +-1. Its `adapt_info` records the
    relocation (`parallel.adapt.relocate`). Collective."""
    from pfmembrane.parallel.adapt import relocate
    PETSc = petsc.start()
    comm = petsc.comm(comm if comm is not None else
                      (result.grid.comm if result.grid is not None else None))
    scene, basis = result.scene, result.basis
    stage = PETSc.Log.Stage('pfAdapt')
    stage.push()
    try:
        if any(not np.array_equal(r.nodes, result.nodes) for r in along):
            raise ValueError("adapt along results on other nodes")
        xy, phi, info = relocate(comm.tompi4py(), result.nodes, result.phi,
                                            scene.box, result.locality(scene.plane),
                                            basis['cutoff'], f, scene.plane,
                                            np.array([r.phi for r in along]) if along else None,
                                            band)
    finally:
        stage.pop()
    grid = Grid(scene, xy, **{**basis, **grid_params}, comm=comm)
    info['of'] = (result.path or 'the result') + (f" and {len(along)} more" if along else '')
    grid.adapt_info, grid.transferred = info, (result, phi)
    return grid
