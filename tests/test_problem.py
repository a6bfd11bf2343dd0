"""The problem object (parallel.problem.Problem) owns its options: whatever a solve,
a continuation, a stability analysis and a second solve push or default under their
prefixes, the PETSc options database is as it was before, a user's value under the
same prefix included; an empty prefix is refused."""
import sys
import warnings

import pytest

import pfmembrane as pf

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def comm():
    return pf.api.petsc(sys.argv[:1]).COMM_SELF


def _database():
    return dict(pf.api.petsc().Options().getAll())


def test_solve_continuation_stability_solve_leave_the_database_as_found(comm):
    db = pf.api.petsc().Options()
    db.setValue('run_stage2_snes_rtol', '1e-9')     # a user's value under the solve's prefix
    db.setValue('unrelated_option', 'kept')
    try:
        before = _database()
        scene = pf.Scene(reduced_volume=0.9, branch='oblate')
        grid = pf.Grid.uniform(scene, nodes=1500, comm=comm)
        res = pf.solve(scene, grid, 0.06, prefix='run_',
                       options={'stage2_snes_rtol': 1e-11, 'pf_stage1_rtol': 1e-4,
                                'stage1_mat_mumps_icntl_14': 40})
        assert res.converged and res.unused_options == []
        points = list(pf.continuation(res, 'reduced_volume', -0.02, 2,
                                      options={'stage2_mat_mumps_icntl_14': 40}))
        assert len(points) == 2
        spectra = pf.stability(points[-1], modes=1, options={'modes_eps_tol': 1e-9})
        assert len(spectra) == 2
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter('always')
            again = pf.solve(scene, grid, 0.06, start=res, prefix='run_',
                             options={'pf_stage1': 'none', 'stage1_tao_type': 'bncg'})
        # -pf_stage1 none creates no stage-1 solver: its option is reported, not kept
        assert again.converged and again.unused_options == ['stage1_tao_type']
        assert any('stage1_tao_type' in str(w.message) for w in caught)
        assert again.energy == pytest.approx(res.energy, rel=1e-10)
        assert _database() == before
    finally:
        db.delValue('run_stage2_snes_rtol')
        db.delValue('unrelated_option')


def test_an_empty_prefix_is_refused(comm):
    from pfmembrane.parallel.problem import Problem
    scene = pf.Scene(reduced_volume=0.9, branch='oblate')
    grid = pf.Grid.uniform(scene, nodes=400, comm=comm)
    before = _database()
    with pytest.raises(ValueError, match='prefix of their own'):
        Problem(grid, scene, 0.1, '', {'stage2_snes_rtol': 1e-8})
    assert _database() == before
