"""Reading the azimuthal spectra of `pf.stability`: which of their modes are
rigid motions of the vesicle rather than shape changes.

`pf.stability` returns one Spectrum per m, whose `rigid` gives the fraction of
each mode's squared norm in the span of mode m's rigid motions (m = 0: the
translation along the axis; m = 1: the translation along x and the rotation
about y; NaN for the other m). A mode with more than `RIGID` of it counts as a
rigid motion: the index per m that a result records (`index_m`) leaves those
out, and so does its lowest eigenvalue per m (`lowest_m`).
"""
import numpy as np

from pfmembrane.kernels.azimuthal import RIGID

__all__ = ['RIGID', 'rigid']


def rigid(spectrum):
    """Whether each mode of `spectrum` (one m of `pf.stability`) is more than
    `RIGID` rigid motion, as a boolean array in the order of its eigenvalues
    (False where `rigid` is NaN). Not collective."""
    return np.asarray(spectrum.rigid) > RIGID
