"""Every number of the README's headline table stands in the generated table its row
links to, and that table names the commit and the machine that measured it."""
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
