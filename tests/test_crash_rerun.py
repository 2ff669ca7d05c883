"""The crash_rerun plugin: a test that kills its xdist worker once passes on its rerun; one that
kills it every time still fails the run."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

_TESTS = '''
import os, pathlib

def test_crashes_once():
    flag = pathlib.Path(os.environ["CRASH_FLAG"])
    if not flag.exists():
        flag.write_text("crashed")
        os.abort()

def test_crashes_always():
    if os.environ.get("CRASH_ALWAYS"):
        os.abort()
'''


def _run(tmp_path: Path, crash_always: bool) -> subprocess.CompletedProcess:
    (tmp_path / "test_native_crash.py").write_text(_TESTS)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent), "CRASH_FLAG": str(tmp_path / "flag")}
    env.pop("CRASH_ALWAYS", None)
    if crash_always:
        env["CRASH_ALWAYS"] = "1"
    cmd = [sys.executable, "-m", "pytest", "-n", "2", "-p", "crash_rerun", "-p", "no:cacheprovider", "-c", os.devnull,
           "--rootdir", str(tmp_path), str(tmp_path / "test_native_crash.py")]
    return subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)


def test_a_test_that_crashes_its_worker_once_passes_on_its_rerun(tmp_path):
    run = _run(tmp_path, crash_always=False)
    assert run.returncode == 0, run.stdout
    assert "2 passed, 1 rerun" in run.stdout.splitlines()[-1]


def test_a_test_that_crashes_its_worker_twice_fails(tmp_path):
    run = _run(tmp_path, crash_always=True)
    assert run.returncode == 1, run.stdout
    assert "1 failed, 1 passed, 2 rerun" in run.stdout.splitlines()[-1]   # each crashed once, one again
    assert "crashed while running 'test_native_crash.py::test_crashes_always'" in run.stdout
