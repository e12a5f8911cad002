"""pytest fixtures for tests/blender/test_*.py (pure logic, no Blender). The check_*.py
scripts here are not pytest modules: they run inside Blender (see tests/test_blender.py)."""
import importlib.util
import os

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.fixture(scope="module")
def logic():
    """addon/smooth_ffd/logic.py loaded by path: importing the package itself needs bpy."""
    spec = importlib.util.spec_from_file_location(
        "smooth_ffd_logic", os.path.join(ROOT, "addon", "smooth_ffd", "logic.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod
