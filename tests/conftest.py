import os
import sys

import pytest

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


_LAST_FAILED_ONLY = False   # --lf collects only some files, on purpose


def pytest_configure(config):
    global _LAST_FAILED_ONLY
    _LAST_FAILED_ONLY = bool(getattr(config.option, "lf", False))
    _check_installed()


def _check_installed():
    """Testing the artefact: the installed package must be the one imported, and whole."""
    if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
        import smoothffd
        where = os.path.realpath(smoothffd.__file__)
        source = os.path.realpath(os.path.join(ROOT, "python")) + os.sep
        if where.startswith(source):
            raise RuntimeError(f"SMOOTHFFD_TEST_INSTALLED=1 but smoothffd comes from the source "
                               f"tree ({where}): run without PYTHONPATH=python")
        from smoothffd import _core  # noqa: F401  (an ImportError here fails the run)


# tests/blender/ holds both the scripts that run *inside* Blender (check_*.py and their helpers,
# which tests/test_blender.py drives and pytest does not collect: they are not named test_*.py)
# and pytest suites of the add-on's modules that need no Blender (test_*.py), collected here.


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A test file that yields no tests fails the run, with the reason: a module-level skip
    (`pytest.importorskip` of a module that is missing, `pytest.skip(allow_module_level=True)`)
    or a file whose tests were all lost. A missing native module is a broken set-up, not a
    reason to skip a whole suite; a test that cannot run here skips itself, and says why."""
    outcome = yield
    report = outcome.get_result()
    if _LAST_FAILED_ONLY or not isinstance(collector, pytest.Module):
        return
    if report.skipped:
        why = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = f"{report.nodeid}: the whole file was skipped, so it tests nothing ({why})"
    elif report.passed and not report.result:
        report.outcome = "failed"
        report.longrepr = f"{report.nodeid}: collected no tests"


def pytest_terminal_summary(terminalreporter):
    """The GPU suites' worst CUDA-vs-CPU differences of this run, next to their bounds."""
    agreement = sys.modules.get("agreement")
    if agreement is not None and agreement.WORST:
        for line in agreement.summary():
            terminalreporter.write_line(line)
