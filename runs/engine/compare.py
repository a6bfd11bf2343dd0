"""The equivalence table: two outputs of `equivalence.py` (before and after a change),
each number's relative difference against its tolerance.

    python runs/engine/compare.py BEFORE.txt AFTER.txt > runs/engine/equivalence.md

Tolerances: 1e-12 relative for energies and multipliers; 1e-9 for the adaptive sequence,
whose CVT amplifies rounding; for eigenvalues 1e-9 of the largest |lambda| of their m,
the eigensolver's own tolerance (`parallel.stability`: 1e-10 on the residual) being what
decides their last digits. Exits 1 if a number is missing or out of tolerance.
"""
import ast
import sys


def read(path):
    head, values = [], {}
    for line in open(path):
        if line.startswith('# '):
            head.append(line[2:].strip())
        elif len(line) > 41 and line[40] == ' ' and not line.startswith(('stage', 'adapt')):
            values[line[:40].strip()] = ast.literal_eval(line[41:].strip())
    return head, values


def provenance_line(head):
    """The `#` lines of one output as the provenance line of a page (`pfmembrane.report`)."""
    field = {line.split(' ', 1)[0]: line.split(' ', 1)[1] for line in head}
    commit = field['code'].split(' at ')[0].replace(' (modified)', '+modified')
    cores, rest = field['machine'].split(' cores, ', 1)
    cpu, load = rest.split('; load ')
    return (f"Measured at commit `{commit}` on {field['date']}, {cores} cores ({cpu}), load "
            f"{load.split()[0]} at the start; command `{field['command']}`.")


def tolerance(name):
    if name.startswith('half '):
        return 1e-9
    return 1e-12


def main(before, after):
    (h0, v0), (h1, v1) = read(before), read(after)
    rows, ok = [], True
    for name, old in v0.items():
        new = v1.get(name)
        if new is None:
            rows.append(f"| {name} | {old!r} | missing | | FAIL |")
            ok = False
            continue
        if isinstance(old, list):
            scale = max(abs(x) for x in old)
            diff = max(abs(a - b) for a, b in zip(old, new)) / scale
            tol, shown = 1e-9, f"{min(old):.12g} ... {max(old):.12g}"
        else:
            diff, tol, shown = abs(new - old) / abs(old), tolerance(name), f"{old!r} / {new!r}"
        good = diff <= tol and (not isinstance(old, list) or len(old) == len(new))
        ok &= good
        rows.append(f"| {name} | {shown} | {diff:.1e} | {tol:.0e} | {'ok' if good else 'FAIL'} |")
    print("# The engine before and after: the same numbers\n")
    print(f"Before: {provenance_line(h0)}  \nAfter: {provenance_line(h1)}  \n"
          f"Table: `python runs/engine/compare.py {before} {after}`\n")
    print("| quantity | before / after (spectra: the range) | relative difference | "
          "tolerance | |\n|---|---|---|---|---|")
    print('\n'.join(rows))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main(*sys.argv[1:3]))
