"""Table 4 regenerated from sequence directories: the cell of an eps is the
least energy of its converged steps, a half box is compared with the paper's
full-box row, and differences beyond 0.1 points are counted as misses."""
import re

import h5py

from scripts import load
from pfmembrane.paper import SHARP, SHARP_ERROR
from test_sequence import fake_checkpoint

table4 = load('runs/adapt/table4.py')


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


def parse_cell(text):
    """(error %, grid, the paper's error %, difference) of a cell such as
    '1.00 O31 (1.12, -0.12)'; None for what it does not show."""
    match = re.fullmatch(r'(?:(\S+) (\S+) )?\((\S+?)(?:, (\S+))?\)', text)
    assert match, text
    error, grid, paper, diff = match.groups()
    number = lambda x: None if x is None else float(x)  # noqa: E731
    return number(error), grid, number(paper), number(diff)


def test_the_least_energy_of_an_eps_fills_its_cell(tmp_path, md_tables):
    full = sequence_dir(tmp_path, 'full', 24542, False, [
        ('O31', 0.015, 1.00, True),
        ('O32', 0.015, 1.01, True),   # a later grid, but a higher energy
        ('O32', 0.01, 0.40, False),   # unconverged: not a cell
        ('O32', 0.005, 0.50, True)])
    half = sequence_dir(tmp_path, 'half', 6176, True, [('O22', 0.007, 0.60, True)])

    rows, within, compared = table4.table([full, half])

    table, = md_tables('\n'.join(rows))
    full_row, half_row = table.rows[:2]
    assert int(full_row['nodes']) == 24597 and full_row['box'] == 'full'
    paper = SHARP_ERROR[24597]
    assert parse_cell(full_row['eps 0.015']) == (1.00, 'O31', round(paper[0.015], 2), -0.12)
    assert parse_cell(full_row['eps 0.01']) == (None, None, round(paper[0.01], 2), None)
    assert parse_cell(full_row['eps 0.005']) == (0.50, 'O32', 0.43, 0.07)
    # a 6,176-node half box stands for the 12,271-node full box
    assert int(half_row['nodes']) == 12271 and half_row['box'] == 'half'
    assert parse_cell(half_row['eps 0.007']) == (0.60, 'O22', 0.57, 0.03)
    assert (within, compared) == (2, 3)
