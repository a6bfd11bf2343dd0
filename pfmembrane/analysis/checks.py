"""The checks of a converged phase field, as checkpoint attributes: phi_h near
the box, the level set's topology and own energy, the sharp-interface shape's."""
import numpy as np

from pfmembrane.analysis import field3d, levelset
from pfmembrane.io import checkpoint

# The topologies of phi_h = 0 of one component, whose level-set energy (the sharp-limit
# estimate) continues a branch's: `branching.topology_lost` ends a branch past them. The others
# (several spheres, a sphere and a torus) get the sum over their components
# (`levelset.components_energy`), not put on the scene's constraints.
ENERGETIC = ('1 sphere', '1 torus')


def phase_field_checks(mpi, xy, phi, attrs, keep=None):
    """phi_h one eps inside the box (`levelset.boundary_phi`) and, where a level
    set exists, its topology (`levelset.topology`: ``topology``, ``components``,
    ``genus``), its smallest feature (`levelset.smallest_feature`: ``feature_size``,
    ``feature_kind``) and, for one sphere, the level set's own energy
    (`levelset.level_set_energy`) and, where the scene has a sharp-interface
    shape, the energy error and level-set distance against it, or for one
    torus its own energy and radii (`levelset.loop_energy`) with its area and
    volume (``level_set_area``, ``level_set_volume``), or for any other
    topology the sum of its components' energies (`levelset.components_energy`;
    NaN with a piece through the box) and, for several, ``component_energies``,
    as attributes; where no comparison was possible, why in ``sharp_note``.
    Rank 0 computes. `keep`, a dict, carries the basis's locality from one
    call to the next on the same nodes (a continuation's points)."""
    result = {}
    if mpi.Get_rank() == 0:
        ckpt = checkpoint.Checkpoint(nodes=xy, phi=phi, attrs=attrs).unfolded()
        keep = {} if keep is None else keep
        field_h = levelset.PhaseField(ckpt, keep.get('beta'))
        keep['beta'] = field_h.beta
        result['boundary_phi'] = levelset.boundary_phi(ckpt, field=field_h)
        try:
            curve = levelset.level_set(ckpt, field=field_h)
            shape = levelset.topology(curve, ckpt.box)
            result.update(topology=shape['label'], components=shape['components'],
                          genus=shape['tori'])
            try:
                feature = levelset.smallest_feature(curve)
                result.update(feature_size=feature.size, feature_kind=feature.kind)
            except (ValueError, RuntimeError):
                pass  # no feature of this curve: the checks below do not need it
            if shape['label'] == '1 torus':   # no sharp torus to compare: its own energy
                energy, radii = levelset.loop_energy(ckpt, curve[0], field_h)
                result.update(level_set_energy=energy, torus_radii=np.asarray(radii),
                              level_set_area=levelset.revolved_area(curve),
                              level_set_volume=levelset.enclosed_volume(curve))
            elif shape['label'] != '1 sphere':  # several components: the sum of their own
                energy, parts = levelset.components_energy(ckpt, curve, field_h)
                result['level_set_energy'] = energy
                if len(parts) > 1:
                    result['component_energies'] = np.array([p.energy for p in parts])
                raise ValueError(f"phi_h = 0 is {shape['label']}, the sharp shape one sphere: "
                                 "no comparison across topologies")
            else:
                try:
                    c = levelset.compare(ckpt, field=field_h, curve=curve)
                except (ValueError, RuntimeError):
                    if shape['label'] == '1 sphere':  # no sharp shape of the scene (a pear)
                        result['level_set_energy'] = levelset.level_set_energy(ckpt, curve,
                                                                            field_h)[0]
                    raise
                result.update(sharp_energy=c['energy_sharp'], sharp_rel_error=c['rel_error'],
                              sharp_dist_max=c['dist_max'], sharp_dist_mean=c['dist_mean'],
                              level_set_energy=c['energy_level_set'])
        except (ValueError, RuntimeError) as e:
            result['sharp_note'] = f"no comparison ({e})"
    return mpi.bcast(result, root=0)


def surface_checks(mpi, xy, phi, attrs, beta):
    """The checks of a field with harmonics, from its 3D level set phi_h = 0
    (`analysis.field3d`): ``components``, ``genus`` (the sum over the components, from
    their Euler characteristics), ``topology`` ('1 sphere', '1 torus', '2 spheres' ...
    by component and genus) and ``level_set_energy`` with ``level_set_error`` its change
    with the marching step, by the rule of the axisymmetric checks
    (`phase_field_checks`): one sphere is put on the scene's area and volume
    (`field3d.projected`: moved along its normal by at most ``level_set_shift`` to the
    scene's reduced volume, scaled; NaN where no such move is found), any other surface
    has its own Canham-Helfrich energy, each component with its orientation
    (`levelset.loop_energy`'s reason: at C0 = 0 a torus's energy depends on its reduced
    volume alone, and near the Clifford torus's conformal family only to second order);
    with ``level_set_area``, ``level_set_volume`` and ``level_set_step`` (the finer
    marching step). Rank 0 computes."""
    result = {}
    if mpi.Get_rank() == 0:
        field, box, eps = field3d.of_checkpoint(checkpoint.Checkpoint(xy, phi, attrs), beta)
        k, c0 = float(attrs['k']), float(attrs['c0'])
        m = field3d.measure(field, box, eps, k, c0, field3d.MARCH * eps / 2)
        if (m.components, m.genus) == (1, 0):
            _, energy, bar, shift = field3d.projected(field, box, eps, k, c0,
                                                      float(attrs['radius']),
                                                      float(attrs['reduced_volume']))
        else:
            coarse = field3d.measure(field, box, eps, k, c0)
            energy, bar, shift = m.energy, abs(m.energy - coarse.energy), np.nan
        kinds = ['torus' if p['genus'] == 1 else 'sphere' if p['genus'] == 0
                 else f"genus-{p['genus']:g} surface" for p in m.per_component]
        label = ', '.join(f"{kinds.count(kind)} {kind}{'s' if kinds.count(kind) > 1 else ''}"
                          for kind in dict.fromkeys(kinds)) or 'no surface'
        result.update(components=m.components, genus=m.genus, topology=label,
                      level_set_energy=energy, level_set_error=bar, level_set_shift=shift,
                      level_set_area=m.area, level_set_volume=m.volume,
                      level_set_step=field3d.MARCH * eps / 2)
    return mpi.bcast(result, root=0)
