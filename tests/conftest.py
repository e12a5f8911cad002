import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
# The tests' own helpers (meshes.py, reference.py). `smoothffd` itself comes from the
# environment: the wheel installed in a fresh venv (scripts/test.sh, which sets
# SMOOTHFFD_TEST_INSTALLED=1), or a development build with PYTHONPATH=python.
sys.path.insert(0, HERE)


def pytest_report_header(config):
    try:
        import smoothffd
    except ImportError as e:
        return f"smoothffd: not importable ({e})"
    core = getattr(smoothffd, "_core", None)
    return (f"smoothffd {smoothffd.__version__} from {os.path.dirname(smoothffd.__file__)}"
            f" (_core: {'loaded' if core else 'MISSING'})")


def pytest_configure(config):
    """Testing the artefact: the installed package must be the one imported, and whole."""
    if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
        import smoothffd
        where = os.path.realpath(smoothffd.__file__)
        source = os.path.realpath(os.path.join(ROOT, "python")) + os.sep
        if where.startswith(source):
            raise RuntimeError(f"SMOOTHFFD_TEST_INSTALLED=1 but smoothffd comes from the source "
                               f"tree ({where}): run without PYTHONPATH=python")
        from smoothffd import _core  # noqa: F401  (an ImportError here fails the run)

# tests/blender/ holds scripts that run *inside* Blender; tests/test_blender.py drives them.
collect_ignore = ["blender"]
