"""The paper's data: its box, its scene files and its published energies
(Tables 1-5) that runs are compared with.

Keys: scene branch ('oblate' discocyte, 'prolate' dumbbell), grid (node
count of a uniform grid, or the Table B.6 identifier of an adapted one),
eps. The 296,344-node uniform grid is the paper's finest.
"""
import os

PAPER_BOX = (1.5, 2.0)  # (Rb, Zb) of every scene of the paper


PAPER_EPS = 0.04  # the eps of the paper's Table 1 grids


def paper_spacing(nodes, box, eps=PAPER_EPS):
    """The node count of a uniform grid of `box` with the spacing of `nodes`
    nodes in the paper box, or with `eps` that spacing scaled by eps /
    PAPER_EPS: the ratio of eps to the spacing that PAPER_EPS has there."""
    return round(nodes * box[0] * box[1] / (PAPER_BOX[0] * PAPER_BOX[1])
                 * (PAPER_EPS / eps) ** 2)
SCENE_FILES = {'oblate': 'options/discocyte.opts', 'prolate': 'options/dumbbell.opts'}
FINEST = 296344
SHARP = {'oblate': 9.12657, 'prolate': 8.71756}

UNIFORM = {  # Tables 1 and 2
    ('oblate', 6124): {0.05: 9.71279, 0.04: 9.59056},
    ('oblate', 12271): {0.05: 9.72137, 0.04: 9.59446, 0.03: 9.43775},
    ('oblate', 24597): {0.05: 9.72671, 0.04: 9.59553, 0.03: 9.43483},
    ('oblate', FINEST): {0.05: 9.73989, 0.04: 9.60053, 0.03: 9.43437, 0.025: 9.35488,
                         0.02: 9.28326, 0.015: 9.22399, 0.01: 9.18627},
    ('prolate', 6124): {0.05: 9.29504, 0.04: 9.15560},
    ('prolate', 12271): {0.05: 9.30167, 0.04: 9.15918, 0.03: 9.00361},
    ('prolate', 24597): {0.05: 9.30627, 0.04: 9.16106, 0.03: 9.00310},
    ('prolate', FINEST): {0.05: 9.31650, 0.04: 9.16512, 0.03: 9.00251, 0.025: 8.92706,
                          0.02: 8.86033, 0.015: 8.80628, 0.01: 8.77359},
}

ADAPTED = {  # Tables 3 and 5 (6,124 nodes)
    ('oblate', 'O1'): {0.04: 9.59056},
    ('oblate', 'O11'): {0.04: 9.59678, 0.03: 9.44002},
    ('oblate', 'O12'): {0.03: 9.43506, 0.025: 9.35810, 0.02: 9.28849},
    ('oblate', 'O13'): {0.025: 9.35970, 0.02: 9.28701, 0.015: 9.22588, 0.01: 9.18703},
    ('prolate', 'P1'): {0.04: 9.15559},
    ('prolate', 'P11'): {0.04: 9.16513, 0.03: 9.01027, 0.025: 8.93545},
    ('prolate', 'P12'): {0.03: 9.00358, 0.025: 8.92990, 0.02: 8.86381, 0.015: 8.80003},
    ('prolate', 'P13'): {0.025: 8.92452, 0.02: 8.86090, 0.015: 8.80834, 0.01: 8.77909},
}

SHARP_ERROR = {  # Table 4: relative error (%) of adapted discocytes against SHARP
    6124: {0.03: 3.38, 0.025: 2.55, 0.02: 1.76, 0.015: 1.09, 0.01: 0.66},
    12271: {0.03: 3.34, 0.025: 2.49, 0.02: 1.69, 0.015: 1.11, 0.01: 0.62, 0.007: 0.57},
    24597: {0.03: 3.37, 0.025: 2.51, 0.02: 1.69, 0.015: 1.12, 0.01: 0.63, 0.005: 0.43},
    FINEST: {0.03: 3.37, 0.025: 2.50, 0.02: 1.72, 0.015: 1.07, 0.01: 0.65},
}

# The paper's scene (Section 4: the discocyte of Table 1), the default of every scene:
# reduced volume v, spontaneous curvature C0, radius R of the sphere of equal area,
# bending rigidity k, the (r, z) box, the family of the initial guess.
SCENE = dict(reduced_volume=0.8, c0=0.0, radius=0.4, k=1.0, box=PAPER_BOX, branch='oblate')


def grid_name(path):
    """The grid of a checkpoint named <grid>_eps<eps>.h5 (its stem otherwise)."""
    return os.path.splitext(os.path.basename(path))[0].split('_eps')[0]


def paper_grid(attrs):
    """The paper's node count of the grid a checkpoint's nodes stand for; a half
    box holds half the nodes of its full-box grid."""
    n = int(attrs['n_nodes']) * (2 if attrs.get('symmetric', 0) else 1)
    return min((6124, 12271, 24597, FINEST), key=lambda m: abs(m - n))
