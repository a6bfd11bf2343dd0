"""The shape atlas (runs/atlas/atlas.py): what the phase diagram makes of branches
(least energy, its regions and transitions, events, continuations of a branch), the
branch files a later run reuses (`pfmembrane.result.save_branch`, `read_branch`), and a
small atlas run end to end."""
import json
import math
import subprocess
import sys

import h5py
import numpy as np
import pytest

from pfmembrane.io.checkpoint import CheckpointError
from pfmembrane.result import Result, read_branch, save_branch
from scripts import load

atlas = load('runs/atlas/atlas.py')


def _point(v, level, topology='1 sphere', direction=-1, fold=0, bifurcation=0, index=0):
    return dict(v=v, E=level + 1.0, level=level, nu_A=1.0, nu_V=-1.0, index=index,
                topology=topology, fold=fold, bifurcation=bifurcation, its=3, converged=1,
                wall=0.1, arclength=abs(0.95 - v), direction=direction)


def _branch(family, c0, points):
    return dict(family=family, c0=c0, points=points, ends=[], box=(1.0, 1.0), half=True,
                nodes=10, eps_min=0.01, time=1.0, shapes=[])


def _linear(family, c0, e95, slope, vs=np.linspace(0.95, 0.55, 9)):
    """A branch of energies e95 + slope (0.95 - v), the start at v = 0.95 then down."""
    pts = [_point(v, e95 + slope * (0.95 - v), direction=-1 if i else 0)
           for i, v in enumerate(vs)]
    return _branch(family, c0, pts)


def test_the_least_energy_changes_where_two_branches_cross():
    """Two straight branches crossing at v = 0.65: the least is the lower one on either
    side and the transition lies within a grid step of the crossing."""
    a = _linear('prolate', 0.0, 7.0, 10.0)        # 7 + 10 (0.95 - v)
    b = _linear('oblate', 0.0, 8.5, 5.0)          # crosses a at 0.95 - v = 0.3
    vs = atlas.grid_v()
    best = atlas.least([a, b], 0.0, vs)
    assert best[-1][0] == 'prolate' and best[0][0] == 'oblate'
    (v, below, above), = atlas.transitions(best, vs)
    assert (below, above) == ('oblate', 'prolate')
    assert abs(v - 0.65) <= atlas.DV
    i = int(np.argmin(abs(vs - 0.8)))
    assert best[i][1] == pytest.approx(7.0 + 10.0 * 0.15)


def test_a_stretch_ends_at_a_topology_change_and_a_fold_counts_both_pieces():
    """A sphere stretch, then a torus: two stretches labelled apart; past a fold both
    pieces over a v compete and the lower wins."""
    pts = [_point(0.95, 7.0, direction=0), _point(0.85, 8.0), _point(0.75, 9.0),
           _point(0.70, 9.5, '1 torus'), _point(0.60, 10.0, '1 torus')]
    runs = atlas.stretches(pts)
    assert [len(r) for r in runs] == [3, 2]
    best = atlas.least([_branch('oblate', 0.0, pts)], 0.0, atlas.grid_v())
    labels = {name for name, _ in best}
    assert labels == {'oblate', 'oblate (1 torus)', ''}   # '' between 0.75 and 0.70
    folded = [_point(0.95, 7.0, direction=0), _point(0.80, 8.0), _point(0.75, 8.4, fold=1),
              _point(0.80, 7.5)]     # the piece back up is lower at 0.80 > v > 0.75
    best = atlas.least([_branch('oblate', 0.0, folded)], 0.0, np.array([0.78]))
    assert best[0][1] == pytest.approx(7.5 + (8.4 - 7.5) * (0.80 - 0.78) / 0.05)


def test_a_fold_is_read_at_the_turn_of_v_not_at_the_point_past_it():
    """v(s) = 0.6 + (s - 0.3)^2 sampled at s = 0, 0.2, 0.45: the first point past the
    turn is at v 0.6225, the turn at 0.6 (exact for a parabola); a turn between two
    points only (a path's first step) gives the point past it."""
    path = [dict(_point(0.6 + (s - 0.3) ** 2, 1.0), arclength=s, index=i)
            for i, s in enumerate((0.0, 0.2, 0.45))]
    path[2]['fold'] = 1
    assert atlas.turning_v(path, 2) == pytest.approx(0.6, abs=1e-12)
    assert atlas.turning_v(path[1:], 1) == pytest.approx(0.6225)
    branch = dict(points=[dict(p, direction=-1) for p in path])
    branch['points'][0]['direction'] = 0
    assert atlas.folds(branch) == ['fold at v 0.6000 (index 1 -> 2)']


def test_events_and_continuations_follow_each_direction_from_the_start():
    start = _point(0.62, 12.0, direction=0)
    down = [_point(0.60, 12.1, direction=-1), _point(0.58, 12.2, '1 torus', direction=-1)]
    up = [_point(0.64, 11.9, direction=1, fold=1, index=1)]
    pts = [start] + down + up
    assert [len(p) for p in atlas.paths(pts)] == [3, 2]
    assert atlas.events(pts) == ['', '', 'topology 1 sphere -> 1 torus', 'fold']
    assert atlas.events([start]) == ['']


def test_an_adapted_switched_branch_resumes_at_the_last_point_of_index_0():
    indices = [1, 0, 1, 0, 1]
    assert atlas.last_stable([_point(0.9, 1.0, index=i) for i in indices]) == 3
    assert atlas.last_stable([_point(0.9, 1.0, index=1)] * 3) == 0


def _shapes(nodes, vs):
    return [Result(nodes, np.arange(5.0) + i, dict(reduced_volume=v, box=np.array([1.0, 2.0]),
                                                    branch='prolate', nu_area=float(i)))
            for i, v in enumerate(vs)]


def test_a_branch_file_gives_back_the_branch(tmp_path):
    nodes = np.random.default_rng(0).random((5, 2))
    b = _linear('prolate', 0.5, 7.0, 10.0, vs=[0.95, 0.9])
    b['shapes'] = _shapes(nodes, (0.95, 0.9))
    b['bifurcation_v'] = math.nan
    path = tmp_path / 'b' / 'prolate_c0.5.h5'
    atlas.save(str(path), b)
    again = atlas.load(str(path))
    assert again['points'] == b['points'] and again['c0'] == 0.5 and again['box'] == (1.0, 1.0)
    assert math.isnan(again['bifurcation_v'])
    np.testing.assert_array_equal(again['shapes'][1].phi, np.arange(5.0) + 1)
    np.testing.assert_array_equal(again['shapes'][0].nodes, nodes)
    assert again['shapes'][0].nodes is again['shapes'][1].nodes  # stored once
    assert again['shapes'][1].attrs['reduced_volume'] == 0.9
    assert again['shapes'][1].attrs['nu_area'] == 1.0  # each point's own attributes
    np.testing.assert_array_equal(again['shapes'][1].attrs['box'], [1.0, 2.0])
    empty = dict(b, points=[], shapes=[], ends=['no start (x)'])
    atlas.save(str(path), empty)
    assert atlas.load(str(path))['ends'] == ['no start (x)']


def test_a_branch_file_of_an_unknown_version_is_refused(tmp_path):
    path = tmp_path / 'b.h5'
    save_branch(path, _shapes(np.zeros((5, 2)), (0.9,)), attrs={'c0': 1.0})
    assert read_branch(path)[1] == {'c0': 1.0}
    with h5py.File(path, 'r+') as f:
        f.attrs['version'] = 99
    with pytest.raises(CheckpointError, match='version 99 unknown'):
        read_branch(path)
    with h5py.File(path, 'r+') as f:
        f.attrs['schema'] = 'something else'
    with pytest.raises(CheckpointError, match='not a pfmembrane-branch file'):
        read_branch(path)


def test_a_branch_file_of_the_layout_before_the_schema_is_read(tmp_path):
    """The unversioned layout atlas.py wrote before (one `nodes`, a `phi` row per point, the
    description and the first point's attributes as JSON): every point gets those
    attributes but for its own v."""
    nodes = np.random.default_rng(1).random((5, 2))
    b = _linear('oblate', 0.0, 7.0, 10.0, vs=[0.95, 0.9, 0.85])
    path = tmp_path / 'oblate_c0.h5'
    with h5py.File(path, 'w') as f:
        f.attrs['branch'] = json.dumps({k: v for k, v in b.items() if k != 'shapes'})
        f.attrs['scene'] = json.dumps(dict(reduced_volume=0.95, box=[1.0, 2.0], c0=0.0))
        f['nodes'] = nodes
        f['phi'] = np.arange(15.0).reshape(3, 5)
    again = atlas.load(str(path))
    assert again['points'] == b['points'] and again['box'] == (1.0, 1.0)
    assert [s.attrs['reduced_volume'] for s in again['shapes']] == [p['v'] for p in b['points']]
    np.testing.assert_array_equal(again['shapes'][2].phi, np.arange(10.0, 15.0))
    np.testing.assert_array_equal(again['shapes'][2].nodes, nodes)


SMALL = ['--eps', '0.06', '--nodes', '3000', '--families', 'prolate', 'oblate', '--c0', '1',
         '--ds', '0.04', '--steps', '4']


def _silhouette(c0, v, label):
    return dict(c0=c0, v=v, label=label, pieces=[[[0.0, 0.1, 0.0], [-0.1, 0.0, 0.1]]])


def test_a_merged_diagram_takes_a_family_from_the_last_atlas_that_has_it(tmp_path):
    """The stomatocyte of a second atlas (at a smaller eps, a sphere of lower energy below
    v 0.65) replaces the first's (a torus): the merged diagram's least state below the
    crossing is it, its branch carries its eps, and only its silhouette is kept."""
    first, second, out = (tmp_path / name for name in ('first', 'second', 'merged'))
    prolate = _linear('prolate', 0.0, 7.0, 10.0)
    torus = _linear('stomatocyte', 0.0, 20.0, 0.0)
    for p in torus['points']:
        p['topology'] = '1 torus'
    sphere = _linear('stomatocyte', 0.0, 8.5, 5.0)      # below the prolate for v < 0.65
    for d, branches, pictures, eps in (
            (first, [prolate, torus], [_silhouette(0.0, 0.8, 'prolate'),
                                       _silhouette(0.0, 0.6, 'stomatocyte (1 torus)')], 0.02),
            (second, [sphere], [_silhouette(0.0, 0.6, 'stomatocyte')], 0.01)):
        d.mkdir()
        atlas.diagram([{k: v for k, v in b.items() if k != 'shapes'} for b in branches],
                      'head', 'command', 'footer', pictures, str(d), dict(eps=eps))
    atlas.merge([str(first), str(second)], str(out))
    with open(out / 'atlas.json') as f:
        merged = json.load(f)
    assert sorted((b['family'], b['eps']) for b in merged['branches']) == \
        [('prolate', 0.02), ('stomatocyte', 0.01)]
    best = atlas.least(merged['branches'], 0.0, atlas.grid_v())
    assert best[0][0] == 'stomatocyte' and best[-1][0] == 'prolate'
    assert sorted(s['label'] for s in merged['silhouettes']) == ['prolate', 'stomatocyte']
    text = (out / 'diagram.md').read_text()
    assert 'eps 0.02: prolate at c0 0; eps 0.01: stomatocyte at c0 0.' in text
    assert 'stomatocyte 0.5500-0.6' in text
    assert (out / 'diagram.png').stat().st_size > 0


def _numbers(out):
    """Every point's values but its seconds and iterations, from OUT/atlas.json."""
    with open(out / 'atlas.json') as f:
        branches = json.load(f)['branches']
    return [[{k: v for k, v in p.items() if k not in ('wall', 'its')} for p in b['points']]
            for b in branches]


def _same(one, two, rtol=1e-8):
    """Equal counts and labels, values to `rtol`: threaded BLAS sums in its own order,
    which moves the last digits between runs (measured: 7e-14 relative)."""
    assert [len(b) for b in one] == [len(b) for b in two]
    for p, q in ((p, q) for a, b in zip(one, two) for p, q in zip(a, b)):
        assert {k: v for k, v in p.items() if isinstance(v, str) or k in ('index', 'fold')} \
            == {k: v for k, v in q.items() if isinstance(v, str) or k in ('index', 'fold')}
        for k in ('v', 'E', 'level', 'nu_A', 'nu_V', 'arclength'):
            assert math.isclose(p[k], q[k], rel_tol=rtol, abs_tol=rtol) or \
                (math.isnan(p[k]) and math.isnan(q[k])), (k, p[k], q[k])


@pytest.mark.slow
@pytest.mark.mpi
def test_two_groups_of_one_rank_give_the_one_rank_atlas(on_groups, child_env, root, tmp_path):
    """Two branches (prolate and oblate at c0 1), up to 5 points each, on two groups of one
    rank and on one rank: the same points; the figures and tables are written, a second
    run reuses the branch files, and the branches follow at a smaller eps on their nodes
    adapted along them, with the basis parameters given. The script runs outside the
    repository."""
    def run(*args):
        done = subprocess.run([sys.executable, str(root / 'runs' / 'atlas' / 'atlas.py'), *SMALL,
                               *args, '--np', '1'], cwd=tmp_path, env=child_env,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout

    one_dir, two_dir, _ = on_groups('runs/atlas/atlas.py', *SMALL)
    one, two = _numbers(one_dir), _numbers(two_dir)
    assert len(one) == 2 and all(len(b) >= 4 for b in one)
    _same(one, two)
    for name in ('branches.md', 'diagram.md', 'energy.png', 'diagram.png'):
        assert (two_dir / name).stat().st_size > 0
    assert run('--out', str(one_dir)).count('(reused)') == 2
    _same(_numbers(one_dir), one, rtol=0.0)
    # the same branches at a smaller eps, each on its coarse branch's nodes adapted by CVT
    adapted = run('--eps', '0.05', '--adapt', '10', '--coarse', str(one_dir), '--steps', '2',
                  '--gamma', '0.7', '--floor', '0.3', '--band', '0.1',
                  '--out', str(one_dir / 'adapted'))
    assert adapted.count('adapt: CVT f=10 band=0.1 of the result and ') == 2
    with open(one_dir / 'atlas.json') as f, open(one_dir / 'adapted' / 'atlas.json') as g:
        coarse, fine = json.load(f)['branches'], json.load(g)['branches']
    for c, b in zip(coarse, fine):
        assert b['nodes'] == c['nodes'] and b['box'] == c['box'] and b['eps_min'] < 0.05
        assert (c['eps'], b['eps']) == (0.06, 0.05) and (c['gamma'], b['gamma']) == (0.8, 0.7)
        assert (c['spacing_floor'], b['spacing_floor']) == (0.0, 0.3)
        solved = atlas.load(atlas.branch_path(one_dir / 'adapted', b['family'], b['c0']))
        assert {s.attrs['spacing_floor'] for s in solved['shapes']} == {0.3}  # the grids' own
        assert solved['shapes'][0].attrs['adapt_band'] == 0.1
        assert len(b['points']) == 3 and all(p['converged'] for p in b['points'])
