"""The stability study: the method at the edges of its range, and how each run ends.

    python runs/extremes/extremes.py --out runs/extremes [--np 2] [--force] [--only NAME,...]
                                     [--timeout 1200]

Each case of `CASES` is one `mpiexec -n NP python -m pfmembrane` run: the scene of its branch
(`pfmembrane.paper.SCENE_FILES`, found from the repository root), the grid and eps of `GRID`
(about 3000 uniform nodes in the paper's 1.5 x 2 box, eps = 0.06), then the case's own
options, writing OUT/<name>.h5. The cases probe the
resolution rule (eps at and below eps_min, with and without -pf_force), the max-ent locality up
to the Delaunay limit, the reduced volume on both branches and the sphere, the spontaneous
curvature, boxes too small for the vesicle, and grids graded by a strong CVT adaptation.

A case with a `parent` needs that case's converged checkpoint: to restart from (``{parent}``
in its options) or for its eps, `eps_ratio` times the eps_min of the parent's grid. The
parents of the cases named by --only run too; the other cases keep their rows in the table
from their saved records. A case is not run again (unless --force) when its record
OUT/<name>.json (command, exit status, stderr line) has the same command and its checkpoint
exists and is newer than its parent's; refused runs write no checkpoint and run again (a few
seconds each). A run still going after --timeout seconds gets SIGTERM, checkpoints
its last iterate (converged = 0) and counts as failed. Each run's output goes to OUT/<name>.log.

OUT/extremes.md, headed by the provenance of the measurement (`report.provenance`), and
OUT/extremes.json (OUT: runs/extremes of the repository by default, whatever the working
directory): one row per case (in the order of `CASES`) with energy, iterations, max |phi|,
relative area and volume residuals, exit status, the stderr reason of a
refusal or failure, and a verdict: "converged" (with the flags of `flags` when the result is
doubtful), "refused: <reason>", "failed: <reason>" or "not run: <reason>". The exit status is 0
when every selected case ended as its expectation (`EXPECT`) says, 1 otherwise.
"""
import argparse
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass

import numpy as np

import pfmembrane as pf
from pfmembrane import report
from pfmembrane import series as launch
from pfmembrane.analysis.levelset import BOUNDARY_TOL, PhaseField, boundary_phi, enclosed_volume, membrane
from pfmembrane.cli.runner import CheckpointError, converged
from pfmembrane.paper import SCENE_FILES as SCENE

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Grid and eps of every case unless its options say otherwise (later options win).
GRID = ('-pf_nodes', '3000', '-pf_box', '1.5,2', '-pf_eps', '0.06')
# A relative energy difference to the same scene in another box above this is a box effect:
# the grid alone moves it far less (3978 and 6111 uniform nodes in the 1.5 x 2 box agree to
# 1e-5 at eps = 0.05).
BOX_TOL = 5e-3
# phi_h = 0 farther than this many R from the sharp-interface shape of the scene: another branch.
OFF_BRANCH = 0.25
# Seconds a run stopped at its time limit has to checkpoint before it is killed.
GRACE = 60

EXPECT = {
    'converged': 'converges, resolved, clear of the box and on its branch',
    'under-resolved': 'converges, flagged under-resolved',
    'box-dependent': 'converges, with a result that depends on the box',
    'off-branch': 'converges, to a shape of another branch',
    'refused': 'exit status 2 before any solve',
    'reported': 'any end with its reason stated: the edge of the method',
}


@dataclass(frozen=True)
class Case:
    """One run of the study.

    Attributes
    ----------
    name : str
        Its checkpoint is OUT/<name>.h5.
    group : str
        The question it belongs to.
    options : tuple of str
        -pf_* options after the scene and `GRID`; ``{parent}`` stands for the parent's
        checkpoint.
    expect : str
        How the run should end, a key of `EXPECT`.
    branch : str
        'oblate' or 'prolate': the scene (`pfmembrane.paper.SCENE_FILES`).
    parent : str
        Case whose converged checkpoint this one needs ('' for none); it comes earlier in
        `CASES`.
    eps_ratio : float
        If > 0, -pf_eps is this multiple of the eps_min of the parent's grid.
    versus : str
        Case of the same scene with one setting changed, whose energy the table gives this
        one's relative to ('' for none).
    """
    name: str
    group: str
    options: tuple
    expect: str
    branch: str = 'oblate'
    parent: str = ''
    eps_ratio: float = 0.0
    versus: str = ''


VOLUMES = (0.99, 0.95, 0.9, 0.8, 0.7, 0.65, 0.6)
# The prolate shapes are long at low v (spheroid semi-axis 1.05 at v = 0.6, which needs
# Zb >= 2.46 with the 3 eps margin): one 1 x 3 box of the reference's spacing for the branch.
PROLATE_BOX = ('-pf_box', '1,3')
# The box cases run at eps = 0.05 on grids of one spacing (about 0.030): the roomy box of
# the paper, its narrower [0,1] x [0,2], smaller ones, and one the initial spheroid cannot fit.
BOX_EPS = ('-pf_eps', '0.05')

CASES = (
    Case('reference', 'reference', (), 'converged'),
    Case('eps-limit', 'resolution', (), 'converged', parent='reference', eps_ratio=1.0),
    Case('eps-limit-0.999', 'resolution', (), 'refused', parent='reference', eps_ratio=0.999),
    Case('eps0.04', 'resolution', ('-pf_eps', '0.04'), 'refused'),
    Case('eps0.04-force', 'resolution', ('-pf_eps', '0.04', '-pf_force'), 'under-resolved'),
    *(Case(f'gamma{g}', 'gamma', ('-pf_gamma', g), 'converged', versus='reference')
      for g in ('0.6', '1')),
    Case('gamma2', 'gamma', ('-pf_gamma', '2'), 'reported', versus='reference'),
    # -help: node a is used where exp(-beta_a d^2) >= cutoff; with beta_a = gamma / h_a^2 the
    # default 1e-6 leaves a support radius of 1.9 h_a at gamma = 4, 1.5 h_a at gamma = 6,
    # hardly past the nearest neighbours; 1e-10 gives 2.4 h_a and 2.0 h_a.
    *(Case(f'gamma{g}', 'gamma', ('-pf_gamma', g, '-pf_cutoff', '1e-10'), 'reported',
           versus='reference') for g in ('4', '6')),
    *(Case(f'oblate-v{v:g}', 'reduced volume', ('-pf_reduced_volume', f'{v:g}'),
           'converged' if v >= 0.7 else 'reported')
      for v in VOLUMES if v != 0.8),   # v = 0.8 is the reference
    *(Case(f'prolate-v{v:g}', 'reduced volume', ('-pf_reduced_volume', f'{v:g}', *PROLATE_BOX),
           'converged' if v >= 0.7 else 'reported', branch='prolate')
      for v in VOLUMES),
    Case('sphere', 'reduced volume', ('-pf_reduced_volume', '1'), 'reported'),
    *(Case(f'v{v}-c0{c0}', 'spontaneous curvature', ('-pf_reduced_volume', v, '-pf_c0', c0),
           'converged' if abs(float(c0)) < 2 else 'reported',
           versus='reference' if v == '0.8' else f'oblate-v{v}')
      for v in ('0.8', '0.9') for c0 in ('-2.5', '-1', '+1', '+2.5')),
    Case('box-roomy', 'box', ('-pf_nodes', '4000', *BOX_EPS), 'converged'),
    Case('box-paper', 'box', ('-pf_box', '1,2', '-pf_nodes', '2667', *BOX_EPS),
         'box-dependent', versus='box-roomy'),
    Case('box-compact', 'box', ('-pf_box', '0.8,1', '-pf_nodes', '1067', *BOX_EPS),
         'box-dependent', versus='box-roomy'),
    Case('box-tight', 'box', ('-pf_box', '0.7,1', '-pf_nodes', '933', *BOX_EPS),
         'box-dependent', versus='box-roomy'),
    Case('box-small', 'box', ('-pf_box', '0.6,2', '-pf_nodes', '1600', *BOX_EPS), 'refused'),
    Case('graded-f1000', 'graded grid', ('-pf_restart', '{parent}', '-pf_adapt', '1000',
                                         '-pf_eps', '0.03'), 'converged', parent='reference'),
    Case('graded-eps0.02', 'graded grid', ('-pf_restart', '{parent}', '-pf_eps', '0.02',
                                           '-pf_force'), 'reported', parent='graded-f1000'),
)
BY_NAME = {case.name: case for case in CASES}

HEADER = ('case', 'group', 'grid', 'options', 'eps', 'eps/eps_min', 'E', 'E vs', 'E sharp',
          'vs sharp', 'd sharp', 'v of phi_h=0', 'its (1+2)', 'max abs phi', 'dA/A0', 'dV/V0',
          'phi_h 1 eps in', 'run s', 'wall s', 'converged', 'exit', 'under-resolved',
          'verdict', 'expected')


def select(names):
    """The cases named (all for None) and the parents they need, in the order of `CASES`.

    Raises
    ------
    ValueError
        For a name that is not a case.
    """
    if names is None:
        return list(CASES)
    unknown = [n for n in names if n not in BY_NAME]
    if unknown:
        raise ValueError(f"unknown case {', '.join(unknown)}; the cases are: "
                         f"{', '.join(BY_NAME)}")
    wanted = set()
    for name in names:
        while name and name not in wanted:
            wanted.add(name)
            name = BY_NAME[name].parent
    return [case for case in CASES if case.name in wanted]


def checkpoint_path(out, name):
    return os.path.join(out, f"{name}.h5")


def option_value(argv, name):
    """The last value given to -pf_<name> in `argv`, or None."""
    values = [argv[i + 1] for i, token in enumerate(argv[:-1]) if token == f'-pf_{name}']
    return values[-1] if values else None


def command(case, out, nprocs, parent_attrs=None):
    """The argv of the run of `case`; `parent_attrs` are those of its parent's checkpoint."""
    options = [token.replace('{parent}', checkpoint_path(out, case.parent))
               for token in case.options]
    if case.eps_ratio:
        # repr: exactly the parent's float, so that a ratio of 1 sits on the limit itself.
        options += ['-pf_eps', repr(case.eps_ratio * float(parent_attrs['eps_min']))]
    return launch.command(nprocs, '-options_file', os.path.join(ROOT, SCENE[case.branch]),
                          *GRID, *options,
                          '-pf_output', checkpoint_path(out, case.name))


def reason_line(stderr):
    """The application's own line on stderr without its prefix and checkpoint note, or ''.

    mpiexec adds its own report of a failed rank after it; the application's line is the
    last one starting with ``pfmembrane:``.
    """
    own = [line for line in stderr.splitlines() if line.startswith('pfmembrane:')]
    if not own:
        return ''
    text = re.sub(r'^pfmembrane:\s*(error:\s*)?', '', own[-1])
    return re.sub(r'\s*\(checkpoint .* marked converged = 0\)$', '', text).strip()


def printed_eps_min(stdout):
    """eps_min from the application's grid line, or None when it never built the grid."""
    found = re.search(r'^grid: .* eps_min ([0-9.eE+-]+)', stdout, flags=re.M)
    return float(found.group(1)) if found else None


def execute(argv, timeout):
    """Run `argv` with a time limit.

    Returns
    -------
    dict
        ``status`` (exit status), ``stdout``, ``stderr``, ``seconds``, ``timed_out``.
    """
    t0 = time.time()
    # A session of its own: `stop` finds the ranks by it.
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=launch.environment(), start_new_session=True)
    timed_out = False
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        timed_out = True
        stdout, stderr = stop(proc)
    except BaseException:
        # In its own session the run does not see the terminal's Ctrl-C: pass it on.
        stop(proc)
        raise
    return dict(status=proc.returncode, stdout=stdout, stderr=stderr,
                seconds=time.time() - t0, timed_out=timed_out)


def stop(proc):
    """End a run: SIGTERM to its ranks, then SIGKILL to every process of its session if it is
    still there after `GRACE` seconds. Returns its (stdout, stderr).

    The ranks are signalled directly, as a batch system does: they checkpoint their last
    iterate and exit. mpiexec, signalled instead, would pass SIGTERM on only after
    ``odls_base_sigkill_timeout`` seconds and kill the ranks as long again later.
    """
    ranks = [pid for pid in session(proc.pid) if pid != proc.pid]
    _signal(ranks or [proc.pid], signal.SIGTERM)
    try:
        return proc.communicate(timeout=GRACE)
    except subprocess.TimeoutExpired:
        _signal(session(proc.pid), signal.SIGKILL)
        return proc.communicate()


def _signal(pids, signum):
    for pid in pids:
        try:
            os.kill(pid, signum)
        except ProcessLookupError:  # ended meanwhile
            pass


def session(sid):
    """Ids of the live processes of session `sid` (Linux /proc)."""
    members = []
    for entry in os.listdir('/proc'):
        try:
            if entry.isdigit() and os.getsid(int(entry)) == sid:
                members.append(int(entry))
        except OSError:  # gone meanwhile
            pass
    return members


def run_case(case, out, argv, timeout):
    """Run one case and save its record (OUT/<name>.json) and output (OUT/<name>.log)."""
    path = checkpoint_path(out, case.name)
    print(' '.join(argv), flush=True)
    t0 = time.time()
    done = execute(argv, timeout)
    with open(os.path.join(out, f"{case.name}.log"), 'w') as f:
        f.write(done['stdout'] + done['stderr'])
    record = dict(command=argv, status=done['status'], reason=reason_line(done['stderr']),
                  seconds=done['seconds'], timed_out=done['timed_out'], timeout=timeout,
                  eps_min=printed_eps_min(done['stdout']),
                  # Refused runs write none: a file there is from an earlier run.
                  checkpoint=os.path.exists(path) and os.path.getmtime(path) >= t0)
    with open(os.path.join(out, f"{case.name}.json"), 'w') as f:
        json.dump(record, f, indent=1)
    return record


def saved_record(case, out, argv):
    """The record of an earlier run of exactly `argv`, or None.

    None also when the record names a checkpoint that is gone or older than its parent's
    (it started from an earlier parent).
    """
    try:
        with open(os.path.join(out, f"{case.name}.json")) as f:
            record = json.load(f)
    except (OSError, ValueError):
        return None
    if record.get('command') != argv:
        return None
    if record.get('checkpoint'):
        path = checkpoint_path(out, case.name)
        parent = checkpoint_path(out, case.parent) if case.parent else None
        if not os.path.exists(path) or (parent and os.path.getmtime(parent) > os.path.getmtime(path)):
            return None
    return record


def level_set_shape(ckpt, field):
    """Reduced volume of the surface phi_h = 0 and its number of pieces.

    Not collective. The volume and area are those of the revolved polyline of
    `limit.membrane` (`field` is the checkpoint's phi_h); the reduced volume is
    None unless the level set is one piece.
    """
    pieces = membrane(ckpt, field=field)
    if len(pieces) != 1:
        return None, len(pieces)
    r, z = pieces[0].T
    volume = enclosed_volume(pieces)
    area = np.sum(np.pi * (r[1:] + r[:-1]) * np.hypot(np.diff(r), np.diff(z)))
    return float(volume / (4.0 / 3.0 * np.pi * (area / (4.0 * np.pi)) ** 1.5)), 1


def read(path):
    """The checkpoint at `path` (`pf.read(path).checkpoint()`), or None when it cannot be
    read."""
    try:
        return pf.read(path).checkpoint()
    except CheckpointError:
        return None


def attributes(path):
    """Root attributes of a readable checkpoint, or None."""
    ckpt = read(path)
    return ckpt.attrs if ckpt else None


def grid_label(case, argv, attrs):
    """How the nodes were made, how many and in which box."""
    box = option_value(argv, 'box').replace(',', ' x ')
    if option_value(argv, 'restart'):
        adapt = option_value(argv, 'adapt')
        kind = f"CVT f={adapt} of {case.parent}" if adapt else f"nodes of {case.parent}"
    else:
        kind = 'uniform'
    nodes = int(attrs['n_nodes']) if attrs else f"~{option_value(argv, 'nodes')}"
    return f"{kind}, {nodes} in {box}"


def options_label(case):
    """The case's options as the table shows them."""
    words = [token.replace('{parent}', f"<{case.parent}>") for token in case.options]
    if case.eps_ratio:
        words += ['-pf_eps', f"{case.eps_ratio:g} eps_min({case.parent})"]
    return ' '.join(words)


def blank_row(case):
    """The row of a case before anything is known of its run."""
    return dict(name=case.name, group=case.group, options=options_label(case),
                expect=case.expect, versus=case.versus, status=None, reason='',
                timed_out=False, timeout=None, seconds=None, reused=False, grid=None, eps=None,
                eps_min=None, energy=None, versus_energy=None, versus_box=None, box=None,
                radius=None, sharp_energy=None, sharp_rel_error=None, sharp_dist_max=None,
                level_set_v=None, level_set_pieces=None, stage1_iterations=None,
                stage2_iterations=None, max_phi=None, area_residual=None,
                volume_residual=None, boundary_phi=None, wall_time=None, converged=None,
                under_resolved=None)


def not_run(case, reason):
    """The row of a case that could not run, and why."""
    return finish(dict(blank_row(case), reason=reason))


def measure(case, record, argv, out, reused=False):
    """The table row of a case from its run record and checkpoint.

    Not collective.

    Parameters
    ----------
    case : Case
    record : dict
        From `run_case`.
    argv : list of str
        The command of the run.
    out : str
        Directory of the checkpoints (also of the `versus` case's).
    reused : bool
        The run is an earlier invocation's.

    Returns
    -------
    dict
        Plain numbers and strings (None where not measured).
    """
    row = blank_row(case)
    row['reused'] = reused
    row.update(status=record['status'], reason=record['reason'], timed_out=record['timed_out'],
               timeout=record['timeout'], seconds=record['seconds'], eps_min=record['eps_min'])
    row['eps'] = float(option_value(argv, 'eps'))
    path = checkpoint_path(out, case.name)
    ckpt = read(path) if record['checkpoint'] else None
    a = ckpt.attrs if ckpt else None
    row['grid'] = grid_label(case, argv, a)
    if ckpt:
        field = PhaseField(ckpt)
        radius, v = float(a['radius']), float(a['reduced_volume'])
        area0, volume0 = 4.0 * math.pi * radius ** 2, v * 4.0 / 3.0 * math.pi * radius ** 3
        row.update({key: _plain(a.get(key)) for key in (
            'eps', 'eps_min', 'energy', 'sharp_energy', 'sharp_rel_error', 'sharp_dist_max',
            'stage1_iterations', 'stage2_iterations', 'max_phi', 'wall_time', 'converged',
            'under_resolved', 'radius')})
        row.update(area_residual=(float(a['area']) - area0) / area0,
                   volume_residual=(float(a['volume']) - volume0) / volume0,
                   box=[float(b) for b in ckpt.box], boundary_phi=boundary_phi(ckpt, field=field))
        row['level_set_v'], row['level_set_pieces'] = level_set_shape(ckpt, field)
    if case.versus:
        vpath = checkpoint_path(out, case.versus)
        va = attributes(vpath) if converged(vpath) else None
        if va is not None:
            row.update(versus_energy=float(va['energy']), versus_box=[float(b) for b in va['box']])
    return finish(row)


def _plain(value):
    """A checkpoint attribute as a JSON value: ints stay ints, non-finite floats are None."""
    value = value.item() if hasattr(value, 'item') else value
    if value is None or isinstance(value, int):
        return value
    return float(value) if math.isfinite(value) else None


OVERSHOOT = 1.01  # max |phi| above this is named in the verdict (not a failure)


def flags(row):
    """What makes a converged result doubtful, as (kind, text) pairs.

    Under-resolved (eps below the grid's eps_min, run with -pf_force); box-dependent (phi_h
    one eps inside the box above -1 + `BOUNDARY_TOL`, or an energy more than `BOX_TOL` away
    from the same scene in another box); off-branch (phi_h = 0 farther than `OFF_BRANCH` R
    from the sharp-interface shape of the scene).
    """
    found = []
    if row['under_resolved']:
        found.append(('under-resolved', f"under-resolved (eps/eps_min {row['eps'] / row['eps_min']:.2f})"))
    if row['boundary_phi'] is not None and row['boundary_phi'] > -1.0 + BOUNDARY_TOL:
        found.append(('box-dependent', f"phi_h {row['boundary_phi']:.4f} one eps inside the box"))
    if (row['versus_energy'] is not None and row['versus_box'] != row['box']
            and abs(row['energy'] / row['versus_energy'] - 1.0) > BOX_TOL):
        found.append(('box-dependent', f"E {_percent(row['energy'] / row['versus_energy'] - 1.0)}"
                                       f" vs {row['versus']} in a {_box(row['versus_box'])} box"))
    if row['sharp_dist_max'] is not None and row['sharp_dist_max'] > OFF_BRANCH * row['radius']:
        found.append(('off-branch', f"phi_h = 0 up to {row['sharp_dist_max']:.3f} from the "
                                    "sharp-interface shape"))
    return found


def verdict(row):
    """How the case ended, in words: converged (and its flags), refused, failed, not run."""
    status = row['status']
    if status is None:
        return f"not run: {row['reason']}"
    if status == 0:
        notes = [text for _, text in flags(row)]
        if row['max_phi'] is not None and row['max_phi'] > OVERSHOOT:
            notes.append(f"overshoot: max |phi| {row['max_phi']:.4f} > {OVERSHOOT:g}")
        return ', '.join(['converged'] + notes)
    if row['timed_out']:
        return f"failed: timed out after {row['timeout']:g} s"
    reason = row['reason'] or f"exit status {status} without a reason on stderr"
    return f"{'refused' if status == 2 else 'failed'}: {reason}"


def as_expected(row):
    """Whether the case ended as its expectation says (`EXPECT`)."""
    status, expect = row['status'], row['expect']
    if status is None:
        return False
    if expect == 'refused':
        return status == 2
    if expect == 'reported':
        return status == 0 or row['timed_out'] or bool(row['reason'])
    kinds = {kind for kind, _ in flags(row)} if status == 0 else None
    if expect == 'converged':
        return kinds == set()
    return kinds is not None and expect in kinds


def finish(row):
    row['verdict'] = verdict(row)
    row['as_expected'] = as_expected(row)
    return row


def _cell(value, spec):
    """`value` formatted with `spec`, or a dash when not measured."""
    return '—' if value is None else format(value, spec)


def _percent(value):
    return '—' if value is None else f"{100 * value:+.2f}%"


def _box(box):
    return ' x '.join(f"{b:g}" for b in box)


def cells(row):
    """The markdown cells of a row, in the order of `HEADER`."""
    ratio = (row['eps'] / row['eps_min']) if row['eps'] and row['eps_min'] else None
    versus = (f"{100 * (row['energy'] / row['versus_energy'] - 1.0):+.3f}% vs {row['versus']}"
              if row['versus_energy'] and row['energy'] is not None else '—')
    # -1: the stage did not finish, or did not run (-pf_stage1 none).
    its = ('+'.join('—' if n is None or n < 0 else str(n)
                    for n in (row['stage1_iterations'], row['stage2_iterations']))
           if row['stage1_iterations'] is not None else '—')
    overshoot = (f"{row['max_phi']:.4f} ({_percent(row['max_phi'] - 1.0)})"
                 if row['max_phi'] is not None else '—')
    shape = (_cell(row['level_set_v'], '.4f') if row['level_set_pieces'] in (None, 1)
             else f"{row['level_set_pieces']} pieces")
    wall = _cell(row['seconds'], '.1f') + (' (reused)' if row['reused'] else '')
    expected = f"{row['expect']}: {'yes' if row['as_expected'] else 'NO'}"
    values = (row['name'], row['group'], row['grid'] or '—', f"`{row['options']}`" if row['options'] else '',
              _cell(row['eps'], '.4g'), _cell(ratio, '.3f'), _cell(row['energy'], '.5f'), versus,
              _cell(row['sharp_energy'], '.5f'), _percent(row['sharp_rel_error']),
              _cell(row['sharp_dist_max'], '.3f'), shape, its, overshoot,
              _cell(row['area_residual'], '+.1e'), _cell(row['volume_residual'], '+.1e'),
              _cell(row['boundary_phi'], '.4f'), _cell(row['wall_time'], '.1f'), wall,
              _cell(row['converged'], 'd'), _cell(row['status'], 'd'),
              _cell(row['under_resolved'], 'd'), row['verdict'], expected)
    return [str(v).replace('|', '\\|') for v in values]


def table(rows):
    """Markdown lines: header, rule, one line per row."""
    return (['| ' + ' | '.join(HEADER) + ' |', '|' + '---|' * len(HEADER)]
            + ['| ' + ' | '.join(cells(row)) + ' |' for row in rows])


def study(selected, out, nprocs, timeout, force=False):
    """Run (or reuse) the selected cases in order and measure them.

    A selected case runs unless it has a saved record with a checkpoint (and not --force);
    the other cases of `CASES` appear with their saved records, if any, so that a partial
    invocation keeps the rest of the table.

    Returns
    -------
    list of dict
        The rows, in the order of `CASES`; ``selected`` marks those of `selected`.
    """
    rows, attrs = [], {}
    for case in CASES:
        chosen = case in selected
        parent_attrs = attrs.get(case.parent)
        if case.parent and parent_attrs is None:
            if chosen:
                rows.append(dict(not_run(case, f"needs {case.parent}, which has no converged "
                                               "checkpoint"), selected=True))
            continue
        argv = command(case, out, nprocs, parent_attrs)
        record = saved_record(case, out, argv)
        reused = not (chosen and (force or record is None or not record['checkpoint']))
        if not reused:
            record = run_case(case, out, argv, timeout)
        elif record is None:
            continue
        row = dict(measure(case, record, argv, out, reused), selected=chosen)
        rows.append(row)
        if row['status'] == 0:
            attrs[case.name] = attributes(checkpoint_path(out, case.name))
        if chosen:
            print(f"{case.name}: {row['verdict']} ({row['expect']}: "
                  f"{'as expected' if row['as_expected'] else 'NOT as expected'})", flush=True)
    return rows


TITLE = 'Stability study: the method at the edges of its range'


def describe(nprocs, timeout, record):
    """The title, the provenance line of `record` (`report.provenance`) and the
    paragraph above the table."""
    return '\n'.join(report.header(TITLE, record)) + '\n' + (
        f"Stability study: `python runs/extremes/extremes.py --out OUT --np {nprocs} --force` "
        f"(`make extremes`), {nprocs} MPI ranks, one run per case, each limited to "
        f"{timeout:g} s. Unless a case's options say otherwise: the scene of its branch "
        f"(`options/discocyte.opts` or `options/dumbbell.opts`) with `{' '.join(GRID)}`, "
        "the paper's box; the grid column gives the nodes of each run. The prolate branch "
        "runs in a 1 x 3 box of the same spacing, the box cases at eps = 0.05 on grids of "
        "one spacing (about 0.030). The oblate v = 0.8 row is `reference`.\n\n"
        "Columns: eps/eps_min against the grid's resolution limit (from the checkpoint, or "
        "from the grid line a refused run prints); E vs: relative to the same scene with one "
        "setting changed; E sharp, vs sharp, d sharp: the axisymmetric sharp-interface shape of "
        "the scene (`pfmembrane.sharp`; for the sphere E sharp = 2 pi k = 6.28319, the paper's "
        "normalization with H the mean curvature), the relative energy error and the largest "
        "distance from phi_h = 0 to its curve; v of phi_h=0: reduced volume of the surface "
        "phi_h = 0 itself; its: stage 1 inner + stage 2 Newton iterations; max abs phi: over "
        "the nodes, with its overshoot above 1; dA/A0, dV/V0: constraint residuals against "
        "A0 = 4 pi R^2, V0 = v 4/3 pi R^3; phi_h 1 eps in: largest phi_h on the lines one eps "
        "inside the sides where phi = -1 is imposed; run s: the run's own wall time; wall s: "
        "mpiexec included; exit: 0 converged, 1 not converged, 2 refused, 143 stopped at the "
        "time limit. Verdict flags: under-resolved; box-dependent (phi_h one eps inside the "
        f"box above {-1 + BOUNDARY_TOL:g}, or E more than {100 * BOX_TOL:g}% off the same "
        f"scene in another box); off-branch (phi_h = 0 farther than {OFF_BRANCH:g} R from the "
        "sharp shape).\n")


def main(argv=None):
    ap = argparse.ArgumentParser(prog='python runs/extremes/extremes.py',
                                 description=__doc__.splitlines()[0])
    ap.add_argument('--out', default=os.path.join(ROOT, 'runs', 'extremes'),
                    help='directory of checkpoints and tables (default: runs/extremes of the '
                         'repository)')
    ap.add_argument('--np', type=int, default=2, help='MPI ranks per run')
    ap.add_argument('--force', action='store_true', help='run the selected cases again')
    ap.add_argument('--only', default=None, help='comma-separated case names (and their parents)')
    ap.add_argument('--timeout', type=float, default=1200.0, help='seconds allowed per run')
    args = ap.parse_args(argv)
    try:
        cases = select(args.only.split(',') if args.only else None)
    except ValueError as e:
        ap.error(str(e))
    os.makedirs(args.out, exist_ok=True)
    # at the start of the measurement; the command as given (this process's by default)
    record = report.provenance(None if argv is None else ' '.join(
        ['python', 'runs/extremes/extremes.py', *map(shlex.quote, argv)]))
    t0 = time.perf_counter()
    rows = study(cases, args.out, args.np, args.timeout, args.force)
    elapsed = time.perf_counter() - t0
    lines = table(rows)
    total = sum(row['seconds'] or 0.0 for row in rows)
    with open(os.path.join(args.out, 'extremes.md'), 'w') as f:
        f.write(describe(args.np, args.timeout, record) + '\n' + '\n'.join(lines) + '\n\n'
                f"Sum of the runs' wall times, mpiexec included: {total:.0f} s (this "
                f"invocation: {elapsed:.0f} s).\n")
    with open(os.path.join(args.out, 'extremes.json'), 'w') as f:
        json.dump(dict(provenance=record, np=args.np, timeout=args.timeout, grid=GRID,
                       expect=EXPECT, cases=[asdict(c) for c in CASES], rows=rows), f, indent=1)
        f.write('\n')
    print('\n'.join(lines))
    ran = [row for row in rows if row['selected']]
    missed = [row['name'] for row in ran if not row['as_expected']]
    print(f"{len(ran) - len(missed)} of {len(ran)} cases as expected"
          f"{': not ' + ', '.join(missed) if missed else ''}; {elapsed:.0f} s -> "
          f"{os.path.join(args.out, 'extremes.md')}")
    return 1 if missed else 0


if __name__ == '__main__':
    sys.exit(main())
