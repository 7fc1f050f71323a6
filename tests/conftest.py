import os
import tempfile

import pytest
from hypothesis import settings

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
# One BLAS thread per test process, and through the environment per CLI subprocess (set before anything loads
# numpy: OpenBLAS reads it once, at load). OpenBLAS's threads make the small LAPACK calls of the fits 40-60x
# slower in CPU time on 2 busy cores (scipy.linalg.svd of the stand fit's 1190x22 Jacobian: 0.3 ms on one thread,
# 13-20 ms on two at load 2-5: docs/notes/issue-26-suite.md), and pytest-xdist's workers would share the cores
# with them. numba's parallel kernels keep their threads. A developer's own setting wins.
for _blas in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_blas, "1")
# the per-user data folder of CLI subprocesses whose environment is taken before a test's own folder is set (a
# module fixture's, an ENV copied at import): this run's temp folder, never the real one (a calibration records its
# phase costs there: app.workflow.phase_costs)
_USER_DATA = tempfile.TemporaryDirectory(prefix="dualrgb-tests-user-data-")
os.environ.setdefault("DUALRGB_DATA_DIR", _USER_DATA.name)

# the sphere_backend fixture (emulator | firmware on a simulated chip), the firmware mark, --firmware-check;
# pytest loads it after this module ran, so after the BLAS setting above
pytest_plugins = ("sphere_backends",)

# Property tests explore new random examples on every developer run (that is how they find bugs); under CI they
# draw the same examples every time (derandomize), so a landing is judged on a reproducible run. A case found
# locally is pinned with @example beside its test.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")


@pytest.fixture(autouse=True)
def user_data_dir(tmp_path, monkeypatch):
    """Each test's per-user data folder (resources.user_path) is its own temp dir, never the real one."""
    folder = tmp_path / "user-data"
    monkeypatch.setenv("DUALRGB_DATA_DIR", str(folder))
    return folder


# make test runs pytest-xdist with --dist loadscope: each module is one unit of work, handed to the workers in
# collection order. The longest modules (their module fixtures: a study, a day of CLI processes) go first, so that
# none starts last and runs alone on one core while the others wait (longest first); the rest keep their order.
# The order: each module's whole time with 4 workers (module_seconds of docs/notes/issue-26/suite-after-2.json).
LONGEST_FIRST = ("e2e/test_copystand.py", "test_readme_day.py", "e2e/test_stand.py", "faults/test_fault_devices.py",
                 "e2e/test_demo.py", "e2e/test_metadata_cli.py", "e2e/test_json_stdout.py", "e2e/test_no_pty.py",
                 "app/test_ground_truth.py")


def pytest_configure(config):
    """pytest-xdist 3.7+ reorders loadscope's modules by their number of tests (``--loadscope-reorder``, its
    default), which put the stand study (4 tests, the longest module) near the end, alone on one core for minutes:
    the order above is kept instead."""
    if getattr(config.option, "loadscopereorder", None) is not None:
        config.option.loadscopereorder = False


def pytest_collection_modifyitems(config, items):
    tests = os.path.dirname(__file__)
    rank = {os.path.join(tests, *name.split("/")): i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(str(item.path), len(LONGEST_FIRST)))       # stable: the rest as collected


def _utf8(text: str) -> str:
    return text.encode("utf-8", "backslashreplace").decode("utf-8")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A report's captured output and logs made UTF-8: a test of a folder named in another encoding logs its path
    with surrogate escapes (os.fsdecode), and pytest-xdist, which ships every report to the controller as UTF-8,
    lost its worker on them (the test reported as crashed, the run an INTERNALERROR). Surrogates become visible
    backslash escapes; nothing else changes."""
    outcome = yield
    report = outcome.get_result()
    report.sections = [(key, _utf8(text)) for key, text in report.sections]
    if report.longrepr is not None and not isinstance(report.longrepr, tuple):
        text = str(report.longrepr)
        if _utf8(text) != text:
            report.longrepr = _utf8(text)
