"""The layers keep their word: the kernels are numpy/scipy alone, one module writes the
PETSc options database, the public face is a face, and the studies stand on the public API."""
import glob
import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PACKAGE = os.path.join(ROOT, 'pfmembrane')
IMPORT = re.compile(r'^\s*(?:from|import)\s+([\w.]+)(?:\s+import\s+([\w, ]+))?', re.M)


def imports(path):
    """The modules a file imports, `from a import b` counted as a and a.b."""
    with open(path) as f:
        found = set()
        for module, names in IMPORT.findall(f.read()):
            found.add(module)
            found.update(f"{module}.{n.split()[0]}" for n in names.split(',') if n.strip())
        return found


def test_the_kernels_import_neither_mpi_nor_petsc():
    for path in glob.glob(os.path.join(PACKAGE, 'kernels', '*.py')):
        found = {m for m in imports(path) if m.split('.')[0] in ('mpi4py', 'petsc4py')}
        assert not found, f"{path} imports {found}"


def test_one_module_writes_the_options_database():
    writers = set()
    for path in glob.glob(os.path.join(PACKAGE, '**', '*.py'), recursive=True):
        with open(path) as f:
            text = f.read()
        if re.search(r'\.(setValue|delValue|insertString|prefixPush)\(', text):
            writers.add(os.path.relpath(path, ROOT))
    assert writers == {os.path.join('pfmembrane', 'parallel', 'petsc.py')}


def test_the_public_face_is_short():
    lines = sum(len(open(os.path.join(PACKAGE, name)).readlines())
                for name in ('api.py', '__init__.py'))
    assert lines < 300


# Public: the package's top level and these; below it: kernels, parallel, io.
BELOW = ('pfmembrane.kernels', 'pfmembrane.parallel', 'pfmembrane.io', 'pfmembrane.studies')


def test_the_studies_stand_on_the_public_api():
    scripts = glob.glob(os.path.join(ROOT, 'runs', '**', '*.py'), recursive=True)
    assert len(scripts) >= 15
    for path in scripts:
        below = {m for m in imports(path) if m.startswith(BELOW)}
        assert not below, f"{os.path.relpath(path, ROOT)} imports {below}"
