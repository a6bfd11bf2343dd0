"""Pages of measured numbers: where they came from (`provenance`: the code
version, the date, the machine and its load, the command) and markdown tables.

Every generated page starts with `header(title, command)`: a number is only
as good as the record of what measured it.
"""
import datetime
import os
import platform
import shlex
import subprocess
import sys


def _git(*args):
    here = os.path.dirname(os.path.abspath(__file__))
    out = subprocess.run(['git', '-C', here, *args], capture_output=True, text=True)
    return out.stdout.strip() if out.returncode == 0 else ''


def cpu_model():
    """The CPU's model name (/proc/cpuinfo), or what the platform says."""
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                if line.startswith('model name'):
                    return line.split(':', 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance(command=None):
    """What measured the numbers about to be written: `commit` (short hash,
    '+modified' when the package, the options files or a script differ from it,
    'unknown' outside git),
    `date` (UTC), `cores`, `cpu`, `load` (1-minute load average now: call it
    at the start of the measurement) and `command` (default: this process's)."""
    commit = _git('rev-parse', '--short', 'HEAD') or 'unknown'
    # the code and the scenes, not the pages a study rewrites as it goes
    if commit != 'unknown' and _git('status', '--porcelain', '--untracked-files=no', '--',
                                    ':/pfmembrane', ':/options', ':/runs/*.py', ':/runs/**/*.py'):
        commit += '+modified'
    return {'commit': commit,
            'date': datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'),
            'cores': os.cpu_count(), 'cpu': cpu_model(), 'load': round(os.getloadavg()[0], 2),
            'command': command or ' '.join(shlex.quote(a) for a in ['python', *sys.argv])}


def provenance_line(p):
    """One line of a `provenance` record, for the head of a page."""
    return (f"Measured at commit `{p['commit']}` on {p['date']}, {p['cores']} cores "
            f"({p['cpu']}), load {p['load']:.2f} at the start; command `{p['command']}`.")


def header(title, record):
    """The first lines of a page: its title and the provenance line of `record`."""
    return [f"# {title}", '', provenance_line(record), '']


def write(path, lines):
    """Write a page: `lines` one to a line. Returns `path`."""
    with open(path, 'w') as f:
        f.write('\n'.join(lines) + '\n')
    return path


def table(columns, rows):
    """A markdown table: `columns` the header cells, `rows` lists of cells
    (any values; str() of each)."""
    lines = ['| ' + ' | '.join(map(str, columns)) + ' |',
             '|' + '---|' * len(columns)]
    lines += ['| ' + ' | '.join(map(str, row)) + ' |' for row in rows]
    return lines


def iterations(n):
    """Iteration count, '-' for a stage that did not run."""
    return '-' if n < 0 else str(int(n))
