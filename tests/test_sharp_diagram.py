"""The sharp reference phase diagram (`pfmembrane.sharp.diagram`, the rows of
runs/sharp_diagram/diagram.py) on a piece of one row,
checked against `sharp.solve` called directly (its own continuation from the sphere, the
scene's c0 and radius as `analysis.levelset.reference` maps them) and against Seifert, Berndl
and Lipowsky (1991) at c0 = 0: prolate above v 0.652, oblate down to 0.592. The c0 = 0 row
(its stomatocyte at 256 modes) takes about 15 s: those tests are marked slow."""
import pytest

from pfmembrane import sharp
from pfmembrane.paper import SCENE
from pfmembrane.sharp import diagram

R = SCENE['radius']


@pytest.fixture(scope='module')
def c0_zero():
    """The c0 = 0 row around both of its transitions (about 15 s)."""
    return diagram.row(0.0, radius=R, kinds=['prolate', 'oblate', 'stomatocyte'], v_min=0.585,
                       v_max=0.6)


def direct(v, branch, c0=0.0):
    return sharp.solve(v, branch, c0=c0 / (2 * R), radius=R).energy


def energy(result, branch, v):
    b = result['branches'][branch]
    return next(E for w, E in zip(b['v'], b['E']) if abs(w - v) < 1e-9)


@pytest.mark.slow
def test_the_row_energies_are_the_solvers(c0_zero):
    for branch in ('prolate', 'oblate', 'stomatocyte'):
        assert energy(c0_zero, branch, 0.6) == pytest.approx(direct(0.6, branch), rel=1e-8)


@pytest.mark.slow  # a row of the sharp solver: 6 s
def test_the_curvature_is_the_scenes():
    """c0 is the scene's 2 C0 R: the row at c0 = -0.5 is sharp.solve at C0 = -0.5 / (2 R)."""
    result = diagram.row(-0.5, radius=R, kinds=['prolate'], v_min=0.8)
    assert energy(result, 'prolate', 0.8) == pytest.approx(direct(0.8, 'prolate', -0.5),
                                                           rel=1e-8)
    assert energy(result, 'prolate', 0.8) != pytest.approx(direct(0.8, 'prolate'), rel=1e-3)


@pytest.mark.slow
def test_the_crossings_equalize_the_energies(c0_zero):
    crossings = {(t['above'], t['below']): t['v'] for t in c0_zero['transitions']}
    assert set(crossings) == {('prolate', 'oblate'), ('oblate', 'stomatocyte')}
    v = crossings['prolate', 'oblate']
    assert v == pytest.approx(0.652, abs=0.002)
    assert direct(v, 'prolate') == pytest.approx(direct(v, 'oblate'), rel=1e-8)
    # and it is a crossing: 0.001 away the energies differ by far more
    assert abs(direct(v + 1e-3, 'prolate') / direct(v + 1e-3, 'oblate') - 1) > 1e-5
    v = crossings['oblate', 'stomatocyte']
    assert v == pytest.approx(0.592, abs=0.002)
    assert direct(v, 'oblate') == pytest.approx(direct(v, 'stomatocyte'), rel=1e-8)


@pytest.mark.slow
def test_the_regions_follow_the_least_energy(c0_zero):
    assert [r['branch'] for r in c0_zero['regions']] == ['prolate', 'oblate', 'stomatocyte']
    for r in c0_zero['regions']:
        for v in (r['high'], r['low']):
            energies = {b: energy(c0_zero, b, v) for b in c0_zero['branches']
                        if any(abs(w - v) < 1e-9 for w in c0_zero['branches'][b]['v'])}
            assert min(energies, key=energies.get) == r['branch']
