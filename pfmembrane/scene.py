"""The vesicle a solve is asked for: no PETSc, no grid."""
import math
from dataclasses import dataclass, replace
from types import SimpleNamespace

from pfmembrane.io.checkpoint import has_sines
from pfmembrane.io.options import Targets, check_scene
from pfmembrane.paper import SCENE
from pfmembrane.starts import check_fits


@dataclass(frozen=True)
class Scene(Targets):
    """The vesicle: A0 = 4 pi R^2, V0 = v 4/3 pi R^3, bending rigidity k,
    spontaneous curvature c0, the (r, z) box (Rb, Zb) or 'auto', the family
    of the initial guess, and whether it is solved on the half box z >= Zb/2."""
    reduced_volume: float = SCENE['reduced_volume']
    c0: float = SCENE['c0']
    radius: float = SCENE['radius']
    k: float = SCENE['k']
    box: tuple = SCENE['box']
    branch: str = SCENE['branch']
    symmetric: bool = False
    harmonics: int = 0
    dihedral: int = 1
    mirror: bool = True

    def __post_init__(self):
        if self.box != 'auto':
            object.__setattr__(self, 'box', tuple(float(b) for b in self.box))
        check_scene(self)

    @property
    def zc(self):
        return 0.5 * self.box[1]

    @property
    def harmonic_set(self):
        """The azimuthal harmonics (`kernels.harmonics.Harmonics`) phi carries."""
        from pfmembrane.kernels.harmonics import Harmonics
        return Harmonics(self.harmonics, self.dihedral, sines=not self.mirror)

    @property
    def plane(self):
        """z of the mirror plane of a half-box solve, None on the full box."""
        return self.zc if self.symmetric else None

    def sized(self, eps):
        """This scene in the box of `-pf_box auto` for `eps` (`analysis.sizing`),
        or unchanged if it has a box."""
        if self.box != 'auto':
            return self
        from pfmembrane.analysis.sizing import auto_box
        unbounded = SimpleNamespace(**{f: getattr(self, f) for f in
                                       ('radius', 'reduced_volume', 'branch', 'area', 'volume',
                                        'c0', 'k')},
                                    box=(math.inf, math.inf))
        check_fits(unbounded, eps)  # refuses a scene without a start
        return replace(self, box=auto_box(self.branch, self.reduced_volume, eps, self.radius,
                                          self.c0, self.k))

    @classmethod
    def of(cls, attrs):
        """The scene of checkpoint attributes."""
        highest = int(attrs.get('harmonics_highest', 0))
        return cls(reduced_volume=float(attrs['reduced_volume']), c0=float(attrs['c0']),
                   radius=float(attrs['radius']), k=float(attrs['k']),
                   box=tuple(float(b) for b in attrs['box']), branch=str(attrs['branch']),
                   symmetric=bool(attrs.get('symmetric', 0)), harmonics=highest,
                   dihedral=int(attrs.get('dihedral', 1)),
                   mirror=not has_sines(attrs))
