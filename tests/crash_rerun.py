"""pytest plugin: a test whose xdist worker dies (a native crash: a signal, not a failed assert) is
run once more in a fresh worker, and fails only if it crashes again.

CI once lost a worker to a fatal signal in a test that passes on every rerun here (2026-12-03,
tests/test_track_presets.py); this keeps one such crash from failing the run while a repeated crash
still does. Loaded by ``-p crash_rerun`` in pyproject's addopts; a no-op without ``-n``.
"""

import pytest

_crashed: set[str] = set()


@pytest.hookimpl(optionalhook=True)
def pytest_handlecrashitem(crashitem, report, sched):
    """The first crash of a test reschedules it (outcome ``rerun``); a second one stays a failure."""
    if crashitem in _crashed:
        return
    _crashed.add(crashitem)
    sched.mark_test_pending(crashitem)
    report.outcome = "rerun"


def pytest_report_teststatus(report):
    """A rescheduled crash is listed as ``rerun`` (R), not as a failure."""
    if report.outcome == "rerun":
        return "rerun", "R", ("RERUN", {"yellow": True})
    return None
