"""Options: any value either gives sane Params or one UsageError line naming
the option, never another exception (property-based, on PETSc options
databases); unknown and unused names; the output path check."""
import math
import os
import re
import sys
from dataclasses import fields, replace

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import event, given, settings, strategies as st  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from pfmembrane.io import options  # noqa: E402
from pfmembrane.kernels.initial import spheroid_axes  # noqa: E402
from pfmembrane.io.options import Params, UsageError  # noqa: E402
from pfmembrane.parallel.petsc import options_left  # noqa: E402
from pfmembrane.starts import check_run  # noqa: E402

# The small scene of the command-line tests, as option strings.
SCENE = {'eps': '0.06', 'box': '0.8,1.0', 'nodes': '1000', 'radius': '0.4',
         'reduced_volume': '0.8', 'branch': 'oblate'}
FLOATS = [f.name for f in fields(Params) if f.type is float]
INTS = [f.name for f in fields(Params) if f.type is int]
CHOICES = ['branch', 'stage1']
SETTINGS = settings(max_examples=300, deadline=None)
# A floating-point warning would be a second line on stderr.
pytestmark = pytest.mark.filterwarnings('error::RuntimeWarning')

# PETSc takes option values as C strings: no NUL.
texts = st.text(st.characters(blacklist_categories=('Cs',), blacklist_characters='\x00'),
                max_size=20)
numbers = st.floats(allow_nan=True, allow_infinity=True).map(repr)
plausible = st.floats(-0.1, 2.0).map(repr)  # around the admissible ranges
number_texts = st.one_of(numbers, plausible, texts,
                         st.sampled_from(['nan', '-inf', 'Infinity', '1e999', '-0', '1_0']))
integer_texts = st.one_of(st.integers(-10**30, 10**30).map(str), st.integers(-10, 3000).map(str),
                          numbers, texts)
box_texts = st.one_of(st.tuples(numbers, numbers).map(','.join),
                      st.tuples(plausible, plausible).map(','.join),
                      st.lists(numbers, max_size=3).map(','.join), texts)
VALUES = {**{name: number_texts for name in FLOATS}, **{name: integer_texts for name in INTS},
          **{name: texts for name in CHOICES}, 'box': box_texts}


def read(values, extra=()):
    """options.read on a fresh PETSc options database holding -pf_<name> <value>
    and the `extra` (name, value) pairs, and the command line's check that a fresh
    start fits its box (`starts.check_run`)."""
    opts = PETSc.Options()
    opts.create()
    try:
        for name, value in [*(('pf_' + n, v) for n, v in values.items()), *extra]:
            opts.setValue(name, value)
        p = options.read(opts)
        check_run(p)
        return p
    finally:
        opts.destroy()


def assert_sane(p):
    for name in FLOATS:
        assert math.isfinite(getattr(p, name)), name
    assert p.eps > 0 and p.k > 0 and p.radius > 0 and p.gamma > 0
    assert 0 < p.reduced_volume <= 1
    assert p.branch in options.BRANCHES and p.stage1 in options.STAGE1
    assert p.quad_degree in options.QUADRATURE and p.stage1_max_it >= 1
    assert p.nodes >= options.MIN_NODES or p.restart
    assert 0 < p.cutoff < 1 and 0 < p.stage1_rtol < 1 and 0 < p.stage2_rtol < 1
    assert 0 <= p.spacing_floor < 1
    assert p.adapt_band >= 0 and (p.adapt or not p.adapt_band)
    a, c = spheroid_axes(p.area, p.volume, p.branch)
    assert a + 3 * p.eps <= p.box[0] and c + 3 * p.eps <= 0.5 * p.box[1]


def accepted_or_named(values, changed):
    """Read `values`: sane Params, or a UsageError of one printable line that
    names one of the `changed` options."""
    try:
        p = read(values)
    except UsageError as e:
        message = str(e)
        assert message.isprintable() and message, repr(message)
        assert any(re.search(rf'-pf_{name}\b', message) for name in changed), message
        event('refused')
        return
    assert_sane(p)
    event('accepted')


@pytest.mark.slow
@SETTINGS
@given(st.sampled_from(sorted(VALUES)).flatmap(lambda name: st.tuples(st.just(name),
                                                                      VALUES[name])))
def test_one_option_any_value(change):
    name, value = change
    accepted_or_named(dict(SCENE, **{name: value}), [name])


@pytest.mark.slow
@SETTINGS
@given(st.dictionaries(st.sampled_from(sorted(VALUES)), st.just(None), min_size=1).flatmap(
    lambda keys: st.fixed_dictionaries({name: VALUES[name] for name in keys})))
def test_several_options_any_values(changes):
    # The scene fits its box, so any refusal is due to a changed option.
    accepted_or_named(dict(SCENE, **changes), changes)


@SETTINGS
@given(st.fixed_dictionaries({name: st.floats() for name in FLOATS}),
       st.tuples(st.floats(), st.floats()),
       st.integers(-10**6, 10**6), st.sampled_from(options.QUADRATURE + (0, 3, 6)))
def test_validate_params_built_directly(floats, box, nodes, quad_degree):
    p = Params(**floats, box=box, nodes=nodes, quad_degree=quad_degree)
    try:
        options.validate(p)
    except UsageError as e:
        assert str(e).isprintable() and '-pf_' in str(e)
        return
    assert_sane(p)


def test_the_scene_and_the_defaults_are_accepted():
    assert read(SCENE) == replace(Params(), eps=0.06, box=(0.8, 1.0), nodes=1000)
    assert read({}) == Params()


@pytest.mark.slow
@SETTINGS
@given(st.from_regex(r'[pP][fF]_[a-zA-Z0-9_]{1,16}', fullmatch=True).filter(
    lambda name: name.lower()[3:] not in {f.name for f in fields(Params)}))
def test_unknown_pf_names_are_refused(name):
    with pytest.raises(UsageError, match=rf"^unknown option '-{re.escape(name)}'"):
        read(SCENE, extra=[(name, '1')])


def test_a_typo_gets_a_suggestion():
    with pytest.raises(UsageError, match=r"'-pf_epss' \(did you mean -pf_eps\?\)"):
        read(SCENE, extra=[('pf_epss', '0.03')])
    assert read(SCENE, extra=[('PF_EPS', '0.07'), ('other_option', '1')]).eps == 0.07


def test_unused_options_are_those_given_and_never_looked_up():
    opts, comm = PETSc.Options(), MPI.COMM_SELF
    opts.setValue('zz_never_read', '1')
    opts.setValue('zz_read', '2')
    opts.setValue('zz_set_by_the_program', '3')
    try:
        opts.getInt('zz_read')
        with pytest.raises(UsageError, match=r"^option -zz_never_read never used"):
            options.check_unused(opts, comm, ['zz_never_read', 'zz_read'], options_left())
        options.check_unused(opts, comm, ['zz_read'], options_left())
    finally:
        for name in ('zz_never_read', 'zz_read', 'zz_set_by_the_program'):
            opts.delValue(name)


def test_output_path_checked_before_the_run(tmp_path):
    comm = MPI.COMM_SELF
    options.check_output(str(tmp_path / 'new' / 'dirs' / 'state.h5'), comm)
    options.check_output(str(tmp_path / 'state.h5'), comm)
    assert os.listdir(tmp_path) == []  # nothing created, no probe left
    (tmp_path / 'file').write_text('')
    with pytest.raises(UsageError, match="is not a directory"):
        options.check_output(str(tmp_path / 'file' / 'state.h5'), comm)
    with pytest.raises(UsageError, match="is a directory"):
        options.check_output(str(tmp_path), comm)
    with pytest.raises(UsageError, match="cannot create files"):
        options.check_output('/proc/state.h5', comm)


@pytest.mark.parametrize('branch, box', [('oblate', (0.78, 0.98)), ('prolate', (0.55, 2.04))])
def test_an_auto_box_holds_the_shapes_with_seven_eps_to_spare(branch, box):
    from pfmembrane import api
    from pfmembrane.analysis import sizing
    p = read({'box': 'auto', 'branch': branch, 'eps': '0.04'})
    assert p.box == 'auto'  # sized by the scene, above the options layer
    p.box = api.Scene(branch=branch, box='auto').sized(0.04).box
    assert p.box == box
    r, z = np.max(list(sizing.extents(branch, 0.8, 0.4).values()), axis=0) + 7 * 0.04
    # Both shapes fit with the margin; the box is rounded up by less than 0.01.
    assert 0 <= p.box[0] - r < 0.01 and 0 <= p.box[1] - 2 * z < 0.01
    assert read({'box': 'auto', 'restart': 'any.h5'}).box == 'auto'  # the checkpoint's box


def test_an_auto_box_without_a_start_is_refused():
    # The stomatocyte's one start is the sharp shape; at c0 -0.5 (2 C0 R) and v 0.85 the
    # sharp solver does not reach the branch, so nothing sizes the box.
    from pfmembrane import api
    scene = api.Scene(branch='stomatocyte', box='auto', reduced_volume=0.85, c0=-0.5 / 0.8)
    with pytest.raises(UsageError, match=r'-pf_box auto: no stomatocyte at v 0.85'):
        scene.sized(0.04)


@pytest.mark.parametrize('values, message', [
    ({'harmonics': '2', 'dihedral': '1'}, r'-pf_dihedral 1 on the full box: m = 1 holds'),
    ({'harmonics': '2', 'dihedral': '2', 'mirror': '0', 'symmetric': '1'},
     r'-pf_mirror 0: sines'),
    ({'harmonics': '1', 'dihedral': '2', 'tol': '1e-3'}, r'-pf_tol with -pf_harmonics'),
    ({'harmonics': '-1'}, r'-pf_harmonics must be >= 0'),
    ({'harmonics': '1', 'dihedral': '2', 'hessian': 'full'}, r'-pf_hessian: unknown Hessian'),
    ({'harmonics': '1', 'dihedral': '2', 'push': 'bent'}, r'-pf_push: unknown push'),
], ids=['dihedral 1', 'sines', 'tol', 'negative', 'hessian', 'push'])
def test_what_harmonics_cannot_yet_do_is_refused(values, message):
    with pytest.raises(UsageError, match=message):
        read(values)
