"""Spheres of the model's tanh profile: what they hold (`tanh_sphere`), the least
reduced volume at which two of them exist (`split_volume`: the phase field's budding
limit) and their phase field on the axis (`spheres_phi`, a start). No PETSc."""
import math

from pfmembrane.kernels.initial import profile, spheres_distance, tanh_sphere

__all__ = ['tanh_sphere', 'split_volume', 'spheres_phi']


def split_volume(eps, radius):
    """(v, rho): the least reduced volume of two tanh spheres of phase-field area
    4 pi R^2 (`tanh_sphere`): two equal ones, of radius rho;
    v = 1 / sqrt 2 (1 + (pi^2 / 2 + 3) eps^2 / R^2) to second order in eps / R."""
    rho = math.sqrt(radius ** 2 / 2 - (math.pi ** 2 - 6) * eps ** 2 / 6)
    return 2 * tanh_sphere(rho, eps)[1] / (4 / 3 * math.pi * radius ** 3), rho


def spheres_phi(points, radii, heights, zc, eps):
    """The tanh profile of the union of spheres of `radii` centred on the axis at
    zc + `heights`, at `points` (r, z)."""
    return profile(spheres_distance(points, radii, heights, zc), eps)
