"""TAO's own finite-difference check of the augmented-Lagrangian gradient
(`-stage1_tao_test_gradient`), on two ranks."""
import re

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.mpi]


def test_tao_test_gradient_agrees_with_the_hand_coded_gradient(tmp_path, pfm):
    out = pfm('-options_file', 'options/discocyte.opts', '-pf_nodes', '400', '-pf_box', '0.9,1.2',
              '-pf_eps', '0.1', '-pf_force', '-pf_stage1', 'tao', '-stage1_tao_test_gradient',
              '-stage1_tao_max_it', '1', '-pf_stage1_max_it', '1',
              '-pf_output', str(tmp_path / 'tao.h5'))
    cosine = [float(c) for c in re.findall(r'angle cosine = \S+ = ([-0-9.e]+)', out.stdout)]
    error = [float(e) for e in re.findall(r'max-norm \|\|G - Gfd\|\|/\|\|G\|\| = ([-0-9.e+]+)',
                                          out.stdout)]
    assert cosine and len(cosine) == len(error), out.stdout
    assert min(cosine) > 1 - 1e-10
    assert max(error) < 1e-4
