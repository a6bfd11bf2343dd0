"""Table 4 regenerated from sequence directories: the cell of an eps is the
least energy of its converged steps, a half box is compared with the paper's
full-box row, and differences beyond 0.1 points are counted as misses."""
import h5py

from pfmembrane.studies import table4
from pfmembrane.paper import SHARP, SHARP_ERROR
from test_sequence import fake_checkpoint


def energy_of(error):
    """The discocyte energy whose error against the sharp interface is error %."""
    return SHARP['oblate'] * (1 + error / 100)


def sequence_dir(tmp, name, n_nodes, symmetric, runs):
    """A directory of step files, one per (grid, eps, error %, converged)."""
    directory, checkpoints = tmp / name, tmp / f'{name}_runs'
    directory.mkdir()
    checkpoints.mkdir()
    for i, (grid, eps, error, ok) in enumerate(runs):
        path = checkpoints / f'{grid}_eps{eps}.h5'
        fake_checkpoint(path, n_nodes, symmetric, eps=eps, energy=energy_of(error))
        with h5py.File(path, 'a') as f:
            f.attrs['converged'] = int(ok)
        (directory / f'{i:02d}_{grid}_eps{eps}.opts').write_text(f'-pf_output {path}\n')
    return str(directory)


def test_the_least_energy_of_an_eps_fills_its_cell(tmp_path):
    full = sequence_dir(tmp_path, 'full', 24542, False, [
        ('O31', 0.015, 1.00, True),
        ('O32', 0.015, 1.01, True),   # a later grid, but a higher energy
        ('O32', 0.01, 0.40, False),   # unconverged: not a cell
        ('O32', 0.005, 0.50, True)])
    half = sequence_dir(tmp_path, 'half', 6176, True, [('O22', 0.007, 0.60, True)])

    rows, within, compared = table4.table([full, half])

    cells = rows[2].split(' | ')
    assert cells[0] == '| 24597' and cells[1] == 'full'
    column = {e: 2 + i for i, e in enumerate(table4.COLUMNS)}
    assert cells[column[0.015]] == f'1.00 O31 ({SHARP_ERROR[24597][0.015]:.2f}, -0.12)'
    assert cells[column[0.01]] == f'({SHARP_ERROR[24597][0.01]:.2f})'
    assert cells[column[0.005]] == '0.50 O32 (0.43, +0.07)'
    # a 6,176-node half box stands for the 12,271-node full box
    half_cells = rows[3].split(' | ')
    assert half_cells[0] == '| 12271' and half_cells[1] == 'half'
    assert half_cells[column[0.007]] == '0.60 O22 (0.57, +0.03)'
    assert (within, compared) == (2, 3)
