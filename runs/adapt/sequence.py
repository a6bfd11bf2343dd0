"""Run a progressive adaptive sequence (paper Table B.6) and tabulate it
(Tables 3, 4 and 5).

    python runs/adapt/sequence.py options/adapt/discocyte --scene options/discocyte.opts

Each step is an options file of the directory, run in name order as
`python -m pfmembrane -options_file SCENE -options_file STEP` would run it,
but all in one process on NP ranks (started under mpiexec if need be): a
step restarts from the result of an earlier one in memory, on its grid when
the step keeps the nodes and the basis, or with `-pf_adapt f` on a new grid.
Steps whose converged checkpoint exists are not run again (unless --force);
a step whose start did not converge is not run. `--report` only writes the
table of the checkpoints that exist.

Runs from any working directory: the directory and the scene are found
there or else in the repository, whose root is where the steps' own paths
(-pf_output, -pf_restart) and the default table runs/adapt/<name>.md are.
"""
import argparse
import contextlib
import os
import sys
import time

import numpy as np

import pfmembrane as pf
from pfmembrane import report, series
from pfmembrane.cli.runner import Cache, UsageError, converged, option_of, output_of, \
    run_files, steps_of, summary
from pfmembrane.paper import ADAPTED, FINEST, SHARP, SHARP_ERROR, UNIFORM, grid_name, \
    paper_grid

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def found(path):
    """`path` from the working directory if it is there, else from the repository."""
    return os.path.abspath(path if os.path.exists(path) else os.path.join(ROOT, path))


def shown(path):
    """`path` relative to the repository when it is inside it, for the page."""
    rel = os.path.relpath(path, ROOT)
    return path if rel.startswith(os.pardir) else rel


def run(steps, scene, force=False):
    """Run the steps in order in this process; returns {step: wall seconds or
    None if reused}. Collective on COMM_WORLD.

    A step whose restart checkpoint did not converge is not run; the steps
    that do not depend on it still are.
    """
    PETSc = pf.petsc(sys.argv[:1])
    say = PETSc.Sys.Print
    cache, walls = Cache(), {}
    for step in steps:
        out = output_of(step)
        if not force and converged(out):
            walls[step] = None
            continue
        start = option_of(step, 'pf_restart')
        if start is not None and not converged(start):
            say(f"{step}: not run, its start {start} did not converge")
            continue
        say(f"-- {step}")
        t0 = time.perf_counter()
        try:
            res, _ = run_files(scene, step, comm=PETSc.COMM_WORLD, print_fn=say, cache=cache)
            summary(res, out, say)
            status = res.status
            if status:
                say(f"pfmembrane: {res.message}")
        except UsageError as e:
            say(f"pfmembrane: error: {e}")
            status = 2
        walls[step] = time.perf_counter() - t0
        a = res.attrs if status != 2 else {}
        if a:
            say(f"{os.path.basename(step)}: set-up {a['time_setup']:.1f} s, solve "
                f"{np.nansum([a['time_stage1'], a['time_stage2']]):.1f} s, wall "
                f"{walls[step]:.1f} s")
        if status != 0:
            say(f"{step}: exit status {status}")
    return walls


def table(steps, walls):
    """Markdown rows, one per step with the paper's numbers beside ours; the sum
    of the runs' wall times; the rank counts they ran on."""
    rows = ['| step | grid | nodes | gamma | eps | eps_min | E | paper | diff | E finest uniform (paper) | diff '
            '| error vs sharp | paper (Table 4) | max phi | its (1+2) | converged | set-up s (CVT) | solve s '
            '| peak MB/rank | run s | wall s |',
            '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    total, ranks = 0.0, set()
    for step in steps:
        path = output_of(step)
        if not os.path.exists(path):
            continue
        a = pf.read(path).attrs
        branch, eps, energy = str(a['branch']), round(float(a['eps']), 6), float(a['energy'])
        grid = grid_name(path)
        paper = ADAPTED.get((branch, grid), {}).get(eps)
        fine = UNIFORM[(branch, FINEST)].get(eps)
        sharp = 100 * (energy / SHARP[branch] - 1)
        table4 = SHARP_ERROR.get(paper_grid(a), {}).get(eps) if branch == 'oblate' else None
        wall = walls.get(step)
        total += float(a['wall_time'])
        ranks.add(int(a['n_procs']))
        rows.append(
            f"| {os.path.basename(step)} | {grid} | {int(a['n_nodes'])} | {float(a['gamma']):g} | {eps:g} | {a['eps_min']:.4f} "
            f"| {energy:.5f} | {_num(paper)} | {_pct(energy, paper)} | {_num(fine)} | {_pct(energy, fine)} "
            f"| {sharp:.2f}% | {'' if table4 is None else f'{table4:.2f}%'} | {a['max_phi']:.4f} "
            f"| {report.iterations(a['stage1_iterations'])}+{report.iterations(a['stage2_iterations'])} "
            f"| {int(a['converged'])} | {_setup(a)} | {np.nansum([a['time_stage1'], a['time_stage2']]):.1f} "
            f"| {a['peak_rss_mb']:.0f} | {a['wall_time']:.1f} | {'reused' if wall is None else f'{wall:.1f}'} |")
    return rows, total, sorted(ranks)


def _setup(a):
    """Set-up seconds (reading, relocation, basis), with the relocation's own
    where a grid was made and recorded."""
    cvt = a.get('time_adapt', np.nan)
    return f"{a['time_setup']:.1f}" + ('' if np.isnan(cvt) else f" ({cvt:.1f})")


def _num(v):
    return '' if v is None else f'{v:.5f}'


def _pct(value, ref):
    return '' if ref is None else f'{100 * (value / ref - 1):+.3f}%'


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('directory', help='directory of step options files')
    ap.add_argument('--scene', required=True, help='scene options file (options/*.opts)')
    ap.add_argument('--np', type=int, default=2, help='ranks, when not started by mpiexec')
    ap.add_argument('--force', action='store_true', help='rerun steps with a converged checkpoint')
    ap.add_argument('--out', default=None,
                    help='table path (default runs/adapt/<name>.md of the repository)')
    ap.add_argument('--report', action='store_true',
                    help='only write the table of the checkpoints that exist, run nothing')
    ap.add_argument('--note', default='',
                    help='a sentence for the header: how the machine was shared, reruns')
    args = ap.parse_args(argv)
    directory, scene = found(args.directory), found(args.scene)
    name = os.path.basename(os.path.normpath(directory))
    out = os.path.abspath(args.out) if args.out else os.path.join(ROOT, 'runs', 'adapt', name + '.md')
    if not args.report:
        series.ensure_ranks(args.np, __file__, sys.argv[1:])
    record = report.provenance()
    # The steps name their checkpoints relative to the repository.
    with contextlib.chdir(ROOT):
        steps = steps_of(directory)
        t0 = time.perf_counter()
        walls = {} if args.report else run(steps, scene, args.force)
        elapsed = time.perf_counter() - t0
        if not args.report:
            from mpi4py import MPI
            if MPI.COMM_WORLD.Get_rank() != 0:
                return 0
        rows, total, ranks = table(steps, walls)
        status = 0 if all(converged(output_of(s)) for s in steps) else 1
    os.makedirs(os.path.dirname(out), exist_ok=True)
    with open(out, 'w') as f:
        f.write('\n'.join(report.header(f"Adaptive sequence {name}", record)))
        f.write(f"\nAdaptive sequence `{shown(directory)}` (scene `{shown(scene)}`), "
                f"{'/'.join(map(str, ranks))} MPI ranks, {os.cpu_count()} cores. "
                + (args.note.rstrip('.') + '. ' if args.note else '')
                + f"Regenerate: `python runs/adapt/sequence.py {shown(directory)} "
                f"--scene {shown(scene)} --force`.\n\n")
        f.write('\n'.join(rows) + '\n\n')
        f.write(f"Sum of the runs' wall times: {total:.1f} s"
                + ('.\n' if args.report else f" (this invocation: {elapsed:.1f} s).\n"))
    print('\n'.join(rows))
    print(f"sum of run wall times {total:.1f} s -> {out}")
    return status


if __name__ == '__main__':
    sys.exit(main())
