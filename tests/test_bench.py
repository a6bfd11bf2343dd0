"""Benchmarks: the basis measurement on a real grid, the Pareto front, the recommendation."""
import itertools
import json
import math

import numpy as np
import pytest

from scripts import load
from pfmembrane import report

bench = load('runs/bench/bench.py')


@pytest.mark.slow
def test_basis_reports_a_plausible_grid(tmp_path, mpi_env, md_tables):
    bench.main(['basis', '--nodes', '600', '--np', '1', '--out', str(tmp_path)])
    text = (tmp_path / 'basis.md').read_text()
    assert text.startswith('# Basis set-up\n\nMeasured at commit ')
    assert ' cores (' in text.splitlines()[2]
    r, = json.loads((tmp_path / 'basis.json').read_text())['results']
    assert r['nodes'] == 600 and r['ranks'] == 1
    assert r['free_nodes'] < r['nodes']
    # Two triangles per node, six points per triangle, fewer on the boundary.
    assert 10 <= r['quadrature_points'] / r['nodes'] <= 12.5
    # gamma 0.8, cut-off 1e-6: the support radius is 4.2 h. Measured on these 600 nodes:
    # 56.806 basis functions per point, the same to all digits in 5 runs (deterministic).
    # Within 1%: the support grows as the radius squared, so a change of the locality by
    # 0.5% or more fails.
    assert r['mean_support'] == pytest.approx(56.81, rel=0.01)
    s = r['seconds']
    assert all(s[part] > 0 for part in ('nodes', 'spacing', 'partition', 'basis'))
    assert s['grid'] >= s['spacing'] + s['partition'] + s['basis']
    # Peak RSS of the one rank measured 199.6-200.0 MB in 5 runs (OpenBLAS 1, 2 or 4
    # threads), its growth while the grid was built 102.8-103.3 MB; nearly all of it is
    # the imported libraries (numpy, scipy, petsc4py, mpi4py), whose builds differ between
    # machines. A factor 1.5 either way allows for them; dense B0, Br, Bz and BL
    # (points x nodes, 4 x 32 MB here) would not fit in it.
    assert 200 / 1.5 < r['peak_rss_mb'] < 200 * 1.5
    assert 103 / 1.5 < r['grid_rss_mb'] < 103 * 1.5
    # The markdown row shows the JSON's values, rounded (round() rounds as the format does).
    row, = md_tables(text)[0].rows
    assert int(row['requested']) == 600 and int(row['nodes']) == r['nodes']
    assert int(row['free']) == r['free_nodes']
    assert int(row['quadrature points']) == r['quadrature_points']
    assert float(row['points per node']) == round(r['quadrature_points'] / r['nodes'], 2)
    assert float(row['mean support']) == round(r['mean_support'], 1)
    assert int(row['ranks']) == r['ranks']
    for column, part in (('nodes s', 'nodes'), ('spacing s', 'spacing'),
                         ('triangulation + partition s', 'partition'),
                         ('max-ent basis s', 'basis'), ('operators s', 'operators')):
        assert float(row[column]) == round(s[part], 2)
    assert float(row['total s']) == round(s['nodes'] + s['grid'], 2)
    assert float(row['peak MB/rank']) == round(r['peak_rss_mb'])
    assert float(row['grid MB/rank']) == round(r['grid_rss_mb'])


def _dominated(r, records):
    return any(s is not r and s['cost'] <= r['cost'] and abs(s['error']) <= abs(r['error'])
               and (s['cost'] < r['cost'] or abs(s['error']) < abs(r['error']))
               for s in records)


def test_pareto_front_is_the_non_dominated_set():
    rng = np.random.default_rng(7)
    # Integer costs and few error levels make ties in either coordinate common.
    pairs = {(int(c), float(e)) for c, e in zip(rng.integers(1, 30, 80),
                                                rng.choice([-0.03, -0.01, 0.002, 0.01, 0.05], 80))}
    records = [{'name': f"r{k}", 'cost': c, 'error': e} for k, (c, e) in enumerate(sorted(pairs))]
    records.append({'name': 'no reference', 'cost': 0.5, 'error': math.nan})
    front = bench.pareto_front(records)
    expected = {r['name'] for r in records[:-1] if not _dominated(r, records[:-1])}
    assert {r['name'] for r in front} == expected
    assert [r['cost'] for r in front] == sorted(r['cost'] for r in front)
    # Of two runs equal in both, one stays.
    twins = [{'name': 'a', 'cost': 1.0, 'error': 0.1}, {'name': 'b', 'cost': 1.0, 'error': -0.1}]
    assert [r['name'] for r in bench.pareto_front(twins)] == ['a']


def _record(name, cost, error_sharp, scene='discocyte', converged=1, under_resolved=0):
    return {'name': f"{scene}-{name}", 'label': name, 'scene': scene, 'cost': cost,
            'error_sharp': error_sharp, 'error_finest': math.nan, 'converged': converged,
            'under_resolved': under_resolved, 'nodes': 6111, 'eps': 0.01, 'gamma': 0.8,
            'cutoff': 1e-6, 'quad_degree': 4, 'stage1': 'newton', 'ranks': 2, 'adapt': 0.0,
            'restart': '', 'moved': False}


def test_recommend_picks_the_cheapest_converged_run_per_threshold():
    records = [
        _record('coarse', 10, 0.02),
        _record('one', 50, 0.008),
        _record('failed', 30, 0.009, converged=0),
        _record('unresolved', 40, -0.004, under_resolved=1),
        _record('half', 200, 0.004),
        _record('other scene', 20, 0.001, scene='dumbbell'),
        _record('fine', 500, 0.001),
        _record('finer', 400, -0.0019),
    ]
    choice = bench.recommend(records, 'discocyte')
    assert {tol: r['label'] for tol, r in choice.items()} == {
        0.01: 'one', 0.005: 'half', 0.002: 'finer'}
    assert bench.recommend(records, 'discocyte', (0.0005,)) == {0.0005: None}
    assert bench.recommend(records, 'dumbbell')[0.002]['label'] == 'other scene'

    text = bench.recommendation(records, (0.01, 0.0005))
    discocyte = text.split('**Dumbbell**')[0]
    assert '`one`' in discocyte and 'none measured reaches it' in discocyte
    assert '`failed`' not in text and '`unresolved`' not in text


def test_configurations_restart_from_earlier_runs_of_their_scene(tmp_path):
    for quick in (False, True):
        configs = bench.configurations(str(tmp_path), quick)
        names = [c.name for c in configs]
        assert len(set(names)) == len(names)
        for k, c in enumerate(configs):
            if c.restart:
                earlier = {str(tmp_path / (d.name + '.h5')) for d in configs[:k]
                           if d.scene == c.scene}
                assert c.restart in earlier and 'nodes' not in c.options
    base = next(c for c in bench.configurations(str(tmp_path)) if c.label == 'base')
    assert base.ranks == 2 and base.options == bench.BASELINE
    assert base.scene == 'discocyte'


def test_report_and_figure_from_records(tmp_path, md_tables):
    records = [dict(_record(name, cost, err, scene), error_finest=fine, energy=9.5,
                    finest=9.4, wall_time=cost, stage1_iterations=10, stage2_iterations=3,
                    peak_rss_mb=400.0, **{name: math.nan for name in bench.TIME_ATTRS})
               for (name, cost, err, fine), scene in itertools.product(
                   [('a', 10, 0.05, 0.004), ('b', 30, 0.03, 0.001), ('c', 20, 0.04, 0.01)],
                   ('discocyte', 'dumbbell'))]
    missing = [(bench.configurations(str(tmp_path))[-1], 'restart checkpoint missing')]
    text = bench.solve_markdown(records, missing, report.provenance(), quick=False)
    assert '## Recommendation' in text
    assert f"`{missing[0][0].label}`: restart checkpoint missing" in text
    tables = md_tables(text)
    assert [t.section for t in tables] == ['Discocyte', 'Dumbbell']
    for table in tables:
        scene = table.section.lower()
        mine = [r for r in records if r['scene'] == scene]
        assert table.column('run', str) == [r['label'] for r in mine]
        for row, r in zip(table.rows, mine):
            assert float(row['vs finest'].rstrip('%')) == pytest.approx(100 * r['error_finest'])
            assert float(row['vs sharp'].rstrip('%')) == pytest.approx(100 * r['error_sharp'])
            assert float(row['E']) == r['energy'] and float(row['E finest']) == r['finest']
            assert float(row['cost s']) == r['cost'] and int(row['ranks']) == r['ranks']
            assert float(row['peak MB/rank']) == r['peak_rss_mb']
            # The time split is NaN in these records: shown as a dash, not as a number.
            for column in ('set-up s', 'stage 1 s', 'stage 2 s', 'assembly s', 'linear s'):
                assert row[column] == '—'
    bench.plot_pareto(records, str(tmp_path / 'pareto.png'))
    assert (tmp_path / 'pareto.png').stat().st_size > 10000
