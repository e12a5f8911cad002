"""pytest fixtures for tests/blender/test_*.py (the add-on's pure-numpy modules, no Blender).
The check_*.py scripts here are not pytest modules: they run inside Blender (see
tests/test_blender.py)."""
import importlib.util
import os
import sys
import types

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def _load(name):
    """addon/smooth_ffd/<name>.py loaded by path: importing the package itself needs bpy."""
    spec = importlib.util.spec_from_file_location(
        f"smooth_ffd_{name}", os.path.join(ROOT, "addon", "smooth_ffd", f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def inputs():
    return _load("inputs")


@pytest.fixture(scope="module")
def result_arrays():
    return _load("result_arrays")


@pytest.fixture(scope="module")
def addon_core():
    """The add-on's core.py (it asks the `smoothffd` core for its limits and names) with the
    modules it imports, state and inputs, loaded as a package of their own."""
    package = "smooth_ffd_core_test"
    pkg = sys.modules[package] = types.ModuleType(package)
    pkg.__path__ = []
    for name in ("state", "inputs", "core"):
        spec = importlib.util.spec_from_file_location(
            f"{package}.{name}", os.path.join(ROOT, "addon", "smooth_ffd", f"{name}.py"))
        mod = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = mod
        spec.loader.exec_module(mod)
        setattr(pkg, name, mod)
    yield pkg
    for name in ("state", "inputs", "core", ""):
        sys.modules.pop(f"{package}.{name}".rstrip("."), None)
