"""The cost of building a grid, part by part, for benchmarks (runs/bench/bench.py basis).

`measure_grid` times the parts of a uniform grid's set-up as the application makes
them: node generation, nodal spacing, triangulation and partition, the max-ent
basis, and the operators. It needs PETSc (imported when called), unlike the rest of
`pfmembrane.analysis`.
"""
import resource
import time

from pfmembrane.paper import PAPER_BOX

__all__ = ['peak_rss_mb', 'measure_grid']


def peak_rss_mb():
    """This process's peak resident set size so far, in MB (Linux: ru_maxrss in kB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def measure_grid(comm, n, box=PAPER_BOX, gamma=0.8, cutoff=1e-6, degree=4):
    """Build the grid (`Discretization`) of a uniform node set and time its parts.

    Collective. The functions the grid is built from are wrapped while it is
    constructed, so that their time is measured on the calls the application
    makes and the sizes of the max-ent bases they return can be read without being
    evaluated twice. The grid is the bare discretization: `pfmembrane.Grid` adds the
    Hessian products (`gram`) on top.

    Parameters
    ----------
    comm : petsc4py.PETSc.Comm
    n : int
        Requested node count of the uniform node set (`pfmembrane.Grid.uniform`'s).
    box, gamma, cutoff, degree
        The box (Rb, Zb), the max-ent locality, the support cut-off and the degree
        of the Gauss rule (`pfmembrane.Grid`'s `quad_degree`).

    Returns
    -------
    dict
        On every rank: node, free-node and quadrature-point counts, the mean
        support (basis functions per quadrature point), seconds per part
        (largest over the ranks) and peak RSS in MB (largest over the ranks).

    Raises
    ------
    RuntimeError
        The grid no longer calls one of the functions timed.
    """
    from mpi4py import MPI

    from pfmembrane.parallel import discretization
    from pfmembrane.kernels import maxent, nodes as nodesets, quadrature

    mpi = comm.tompi4py()
    rss_start = peak_rss_mb()
    seconds = {'nodes': 0.0, 'spacing': 0.0, 'partition': 0.0, 'basis': 0.0}
    sizes = []  # (support entries, points) of every basis evaluation
    watched = [(discretization, 'spacing_and_locality', 'spacing'),
               (quadrature, 'triangulate', 'partition'),
               (discretization, 'Layout', 'partition'),
               (quadrature, 'rule', 'partition'),
               (maxent, 'local_maxent', 'basis')]
    originals = [getattr(module, name) for module, name, _ in watched]
    calls = [0] * len(watched)

    def timed(k, fn, part):
        def call(*args, **kwargs):
            t = time.perf_counter()
            out = fn(*args, **kwargs)
            seconds[part] += time.perf_counter() - t
            calls[k] += 1
            if part == 'basis':
                sizes.append((int(out.indptr[-1]), len(out.indptr) - 1))
            return out
        return call

    mpi.Barrier()
    t = time.perf_counter()
    xy = nodesets.uniform(box, n)
    seconds['nodes'] = time.perf_counter() - t
    for k, ((module, name, part), fn) in enumerate(zip(watched, originals)):
        setattr(module, name, timed(k, fn, part))
    try:
        t = time.perf_counter()
        grid = discretization.Discretization(comm, xy, box, gamma=gamma, cutoff=cutoff, degree=degree)
        total = time.perf_counter() - t
    finally:
        for (module, name, _), fn in zip(watched, originals):
            setattr(module, name, fn)
    missed = [name for (_, name, _), c in zip(watched, calls) if c == 0]
    if missed:
        raise RuntimeError(f"Grid no longer calls {', '.join(missed)}: update measure_grid")
    # The rest of Grid: axis mirrors, the sparse operators and their ghost layout.
    seconds['operators'] = total - seconds['spacing'] - seconds['partition'] - seconds['basis']
    seconds['grid'] = total
    support, points = (mpi.allreduce(sum(x)) for x in zip(*sizes))
    peak = peak_rss_mb()
    return {'requested': n, 'nodes': len(xy), 'free_nodes': grid.layout.nglobal,
            'quadrature_points': grid.nquad, 'mean_support': support / points,
            'ranks': mpi.Get_size(),
            'seconds': {k: mpi.allreduce(v, op=MPI.MAX) for k, v in seconds.items()},
            'peak_rss_mb': mpi.allreduce(peak, op=MPI.MAX),
            'grid_rss_mb': mpi.allreduce(peak - rss_start, op=MPI.MAX)}
