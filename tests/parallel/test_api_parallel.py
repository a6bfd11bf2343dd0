"""The Python API on COMM_WORLD (run under mpiexec -n 2): a distributed solve
equals the one-rank solve of the same scene, and a grid and its partition
serve several solves."""
import numpy as np
import pytest
from petsc4py import PETSc

import pfmembrane as pf

pytestmark = pytest.mark.slow
SCENE = pf.Scene(reduced_volume=0.8, branch='oblate')
HALF = pf.Scene(reduced_volume=0.8, branch='oblate', symmetric=True)


@pytest.mark.parametrize('scene', [SCENE, HALF], ids=['full box', 'half box'])
def test_ranks_agree_with_one_rank(scene, distributed):
    world = pf.Grid.uniform(scene, nodes=1500)
    alone = pf.Grid.uniform(scene, nodes=1500, comm=PETSc.COMM_SELF)
    many = pf.solve(scene, world, eps=0.075, checks=False)
    one = pf.solve(scene, alone, eps=0.075, checks=False)
    assert many.converged and one.converged
    assert many.energy == pytest.approx(one.energy, rel=1e-10)
    assert np.allclose(many.nu, one.nu, rtol=1e-7)
    assert np.allclose(many.phi, one.phi, atol=1e-7)
    # every rank holds the whole result
    energies = PETSc.COMM_WORLD.tompi4py().allgather(many.energy)
    assert len(set(energies)) == 1


def test_a_grid_serves_eps_and_volume_steps():
    grid = pf.Grid.uniform(SCENE, nodes=1500)
    first = pf.solve(SCENE, grid, eps=0.06, checks=False)
    deflated = pf.Scene(reduced_volume=0.78, branch='oblate')
    step = pf.solve(deflated, grid, eps=0.06, start=first, options={'pf_stage1': 'none'},
                    checks=False)
    assert step.converged and step.attrs['time_setup'] == 0.0
    assert step.attrs['stage1_iterations'] == -1  # straight to the bordered Newton
    assert step.attrs['volume'] == pytest.approx(deflated.volume, rel=1e-10)
    assert step.energy > first.energy  # deflating the discocyte costs bending energy


def test_a_graph_partition_gives_the_bisections_result(distributed):
    cut = pf.Grid.uniform(HALF, nodes=1500)
    graph = pf.Grid.uniform(HALF, nodes=1500, partition='ptscotch')
    assert not np.array_equal(cut.discrete.layout.order, graph.discrete.layout.order)
    a, b = (pf.solve(HALF, g, eps=0.075, checks=False) for g in (cut, graph))
    assert a.energy == pytest.approx(b.energy, rel=1e-10)
    assert np.allclose(a.phi, b.phi, atol=1e-8)


def test_the_partition_is_the_bisection_of_the_free_nodes(distributed):
    from pfmembrane.parallel.partition import bisection
    d = pf.Grid.uniform(HALF, nodes=1500).discrete
    free = np.flatnonzero(~d.dirichlet)
    part = bisection(d.nodes[free], PETSc.COMM_WORLD.getSize())
    assert np.array_equal(d.layout.order, free[np.argsort(part, kind='stable')])


def test_a_redundant_factorization_gives_the_parallel_one_and_its_index(distributed):
    """`-stageN_pc_type redundant`: sequential MUMPS LDL^T on every rank. The same
    iterations and energy as parallel MUMPS, and the stability index (the inertia
    inside the PCREDUNDANT) along a continuation."""
    grid = pf.Grid.uniform(HALF, nodes=1500)
    redundant = {'stage1_pc_type': 'redundant', 'stage2_pc_type': 'redundant'}
    parallel = pf.solve(HALF, grid, eps=0.075, checks=False)
    one = pf.solve(HALF, grid, eps=0.075, options=redundant, checks=False)
    assert one.energy == pytest.approx(parallel.energy, rel=1e-12)
    for key in ('stage1_iterations', 'stage2_iterations'):
        assert one.attrs[key] == parallel.attrs[key]
    step, = pf.continuation(one, 'reduced_volume', -0.02, 1, options=redundant)
    again, = pf.continuation(parallel, 'reduced_volume', -0.02, 1)
    assert one.attrs['index_0'] == step.attrs['index_0'] == again.attrs['index_0'] == 0
    assert step.energy == pytest.approx(again.energy, rel=1e-10)
