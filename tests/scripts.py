"""The study scripts of runs/ as modules, for the tests of their functions:
`load('runs/atlas/atlas.py')` imports it once per process (as `study_atlas_atlas`)."""
import importlib.util
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def load(path):
    """The module of the script at `path` (relative to the repository)."""
    folder, stem = os.path.split(os.path.splitext(path)[0])
    name = f"study_{os.path.basename(folder)}_{stem}"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, path))
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]
