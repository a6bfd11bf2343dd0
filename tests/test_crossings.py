"""The c0 = 0 energy crossings (runs/crossings/crossings.py): the sharp roots, the
spline root of sampled differences, the notes page, and a short phase-field series."""
import math
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from scripts import load

crossings = load('runs/crossings/crossings.py')

# Converged sharp crossings (runs/crossings/notes.md: n = 8 ... 32 and 128 ... 256 agree
# to 1e-6).
PROLATE_OBLATE = 0.65108
OBLATE_STOMATOCYTE = 0.59118


def test_sharp_prolate_oblate_crossing():
    """n = 8 already gives the crossing to 2e-5 (about 2 s); SBL's 0.652 to 1e-3."""
    v = crossings.sharp_crossing('prolate-oblate', n=8, xtol=1e-4)
    assert abs(v - PROLATE_OBLATE) < 1e-4
    assert abs(v - 0.652) < 1e-3


@pytest.mark.slow
def test_sharp_oblate_stomatocyte_crossing():
    """The stomatocyte at n = 64 (some 20 s): within 1e-4 of the converged crossing."""
    v = crossings.sharp_crossing('oblate-stomatocyte', n=64, xtol=1e-5)
    assert abs(v - OBLATE_STOMATOCYTE) < 1e-4
    assert abs(v - 0.592) < 1e-3


def test_the_spline_root_of_sampled_differences():
    vs = np.linspace(0.58, 0.66, 9)
    upper, lower = (vs - 0.6123) * (1 + 3 * vs) + 2.0, np.full_like(vs, 2.0)
    assert crossings.crossing(vs, upper, lower) == pytest.approx(0.6123, abs=1e-9)
    assert crossings.crossing(vs[:2], [1.0, -1.0], [0.0, 0.0]) == pytest.approx(0.585)  # linear
    assert math.isnan(crossings.crossing(vs, upper + 1, lower))
    assert math.isnan(crossings.crossing(vs[:1], upper[:1], lower[:1]))


def _state(v, energy, topology='1 sphere', converged=1):
    return dict(v=v, wall=1.0, attrs=dict(
        converged=converged, energy=energy + 0.3, level_set_energy=energy, sharp_energy=energy,
        topology=topology, nu_area=9.0, nu_volume=-60.0, stage1_iterations=-1,
        stage2_iterations=4))


def test_crossings_skip_states_that_are_not_one_sphere():
    """A pinched stomatocyte (2 spheres) takes no part; the common v of the branches do."""
    series = {'oblate': dict(rows=[_state(v, 10 - 20 * (v - 0.6)) for v in (0.62, 0.61, 0.6, 0.59)]),
              'stomatocyte': dict(rows=[_state(0.62, 10.0), _state(0.61, 10.0),
                                        _state(0.6, 10.0), _state(0.59, 9.0, '2 spheres'),
                                        _state(0.58, 10.0)])}
    assert crossings.phase_field_crossing('oblate-stomatocyte', series,
                                          'level_set_energy') == pytest.approx(0.6, abs=1e-9)
    assert math.isnan(crossings.phase_field_crossing('prolate-oblate', series, 'energy'))


def test_notes_page(tmp_path, md_tables):
    series = {b: dict(branch=b, box=(0.5, 1.0), symmetric=b != 'stomatocyte', nodes=100,
                      eps_min=0.01, rows=[_state(v, e(v)) for v in (0.58, 0.6, 0.62, 0.64, 0.66)])
              for b, e in (('prolate', lambda v: 11 - 20 * (v - 0.651)),
                           ('oblate', lambda v: 11 - 10 * (v - 0.651)),
                           ('stomatocyte', lambda v: 12.3 - 10 * (v - 0.651) - 5 * (0.65 - v)))}
    series['stomatocyte']['rows'].append(_state(0.56, 0.0, converged=0))
    sharp_rows = {name: [(8, 0.65, 1.0), (None, 0.651, 2.0)] for name in crossings.CROSSINGS}
    args = SimpleNamespace(np=2, eps=0.02, nodes=40000, out=str(tmp_path),
                           branch=list(crossings.VOLUMES), options=[])
    crossings.write(sharp_rows, series, args, 12.0, str(tmp_path))
    text = (tmp_path / 'notes.md').read_text()
    assert '--np 2 --eps 0.02 --nodes 40000' in text and 'wall time 12 s' in text
    tables = {t.section: t for t in md_tables(text)}
    for branch, b in series.items():
        table = tables[branch]
        done = [r for r in b['rows'] if r['attrs']['converged']]
        assert table.column('v')[:len(done)] == [r['v'] for r in done]
        for row, r in zip(table.rows, done):
            for column, key in (('E', 'energy'), ('E level set', 'level_set_energy'),
                                ('E sharp', 'sharp_energy')):
                assert float(row[column]) == round(r['attrs'][key], 5)
    failed = tables['stomatocyte'].row('v', '0.56')
    assert failed['E'] == 'not converged' and failed['topology'] == ''
    # The synthetic energies: prolate and oblate cross at v = 0.651, E and level set alike;
    # the oblate and stomatocyte differences keep their sign, so no root.
    po = tables['The crossings'].row('crossing', 'prolate-oblate')
    assert float(po['SBL']) == 0.652 and float(po['sharp (default n)']) == 0.651
    for column in ('phase field, level-set E', 'phase field, E',
                   'sharp E at the same v, spline'):
        assert float(po[column]) == pytest.approx(0.651, abs=5e-5)
    assert float(po['minus SBL']) == pytest.approx(0.651 - 0.652, abs=5e-5)
    ob_st = tables['The crossings'].row('crossing', 'oblate-stomatocyte')
    assert math.isnan(float(ob_st['phase field, level-set E']))


@pytest.mark.slow
def test_a_short_series_stays_on_its_branch():
    """Two prolate states on a coarse half-box grid: one sphere, the level-set energy the
    known eps discrepancy above the sharp one (eps 0.04 on the spacing of 12,271 nodes)."""
    import pfmembrane as pf
    comm = pf.api.petsc(sys.argv[:1]).COMM_WORLD
    args = SimpleNamespace(eps=0.04, nodes=12271, solver={})
    s = crossings.follow('prolate', [0.66, 0.65], args, lambda *a: None)
    assert s['symmetric'] and comm.getSize() == 1
    assert [r['attrs']['topology'] for r in s['rows']] == ['1 sphere'] * 2
    # Level set against sharp, measured (2026-12, serial): +1.267e-2 at v = 0.66, +1.341e-2
    # at v = 0.65. A real discrepancy of the phase field's width, not of the solve: it falls as
    # eps^4 along this branch (runs/crossings: +8.6e-4 at eps 0.02, +5.4e-5 at eps 0.01 at
    # v = 0.66; x16 per halving gives 1.4e-2 at 0.04). The band is the measured values
    # +-1.5e-3 (some 12% of the discrepancy): two runs, of HEAD and of a refactored tree,
    # agreed to all 16 digits, so only a change of the discretisation, the solve or the
    # energies moves them that far.
    for r, measured in zip(s['rows'], (1.267e-2, 1.341e-2)):
        a = r['attrs']
        assert a['level_set_energy'] / a['sharp_energy'] - 1 == pytest.approx(measured, abs=1.5e-3)
