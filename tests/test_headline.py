"""Every number of the README's headline table stands in the generated table its row
links to, and that table names the commit and the machine that measured it."""
import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROVENANCE = re.compile(r"Measured at commit `[0-9a-f]{7,}(\+modified)?` on \d{4}-\d\d-\d\d "
                        r"[\d:]+ UTC, \d+ cores \([^)]+\), load [\d.]+ at the start; command `")
NUMBER = re.compile(r'(?<![\w.])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?%?')


def headline_rows():
    with open(os.path.join(ROOT, 'README.md')) as f:
        text = f.read()
    section = text.split('## Headline results', 1)[1].split('\n## ', 1)[0]
    rows = [line for line in section.splitlines() if line.startswith('| ')]
    return [[cell.strip() for cell in row.strip('|').split(' | ')] for row in rows[1:]]


def test_the_headline_table_has_rows():
    assert len(headline_rows()) >= 3


def test_each_headline_number_stands_in_its_generated_table():
    for result, measured, page in headline_rows():
        link = re.search(r'\]\(([^)#]+)', page).group(1)
        with open(os.path.join(ROOT, link)) as f:
            table = f.read()
        assert PROVENANCE.search(table), f"{link} names no commit and machine"
        for number in NUMBER.findall(measured):
            assert number.lstrip('+') in table, f"{result}: {number} is not in {link}"


def test_each_page_index_names_each_pages_provenance():
    """A study's README that lists its pages with a 'measured' column gives, for each
    linked page, the commit, date, machine and load of that page's own header."""
    header = re.compile(r"Measured at commit `([0-9a-f]+)` on (\S+ \S+ UTC), "
                        r"(\d+ cores \([^)]+\)), load ([\d.]+) at the start")
    checked = 0
    for index in glob.glob(os.path.join(ROOT, 'runs', '*', 'README.md')):
        with open(index) as f:
            lines = f.read().splitlines()
        heads = [i for i, line in enumerate(lines) if line.startswith('| page |')
                 and 'measured' in line]
        for i in heads:
            column = [c.strip() for c in lines[i].strip('|').split('|')].index(
                'measured (commit, date, machine, load at the start)')
            for row in lines[i + 2:]:
                if not row.startswith('| '):
                    break
                cells = [c.strip() for c in row.strip('|').split(' | ')]
                for page in re.findall(r'\]\(([^)]+\.md)\)', cells[0]):
                    with open(os.path.join(os.path.dirname(index), page)) as f:
                        c, date, machine, load = header.search(f.read()).groups()
                    assert f"`{c}`, {date}, {machine}, load {load}" in cells[column], \
                        f"{index}: {page}'s provenance"
                    checked += 1
    assert checked >= 8
