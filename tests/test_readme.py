"""The README's Python API block runs as written (in a fresh interpreter, as a user would)."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow   # a fresh interpreter compiles the fits: left out of `make test-fast`

README = Path(__file__).resolve().parent.parent / "README.md"


def test_the_api_block_runs_and_fits():
    text = README.read_text()
    block = re.search(r"## The Python API\n\n```python\n(.*?)```", text, re.S).group(1)
    out = subprocess.run([sys.executable, "-c", block], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.strip().splitlines()
    assert lines[0].split()[0] in ("ok", "singular")
    assert float(lines[-1].split()[-1]) < 5.0   # median joint error of the batch (deg), starts 5 deg away
