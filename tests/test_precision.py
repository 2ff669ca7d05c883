"""float64 is asked for, not switched on at import (run in fresh interpreters: the tests' own
process has it on)."""

import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow   # fresh interpreters: left out of `make test-fast`

SCRIPT = """
import jax, jax.numpy as jnp
import jaxhand as jh
print("after import:", jax.config.jax_enable_x64, jnp.asarray(1.0).dtype)
try:
    jh.builtin_model("index")
except jh.InputError as err:
    print("error:", err)
jh.enable_x64()
m = jh.builtin_model("index")
print("after enable:", m.dh.dtype, jh.forward(m, m.q_default).tips.dtype)
"""


def test_import_leaves_float32_code_alone_and_models_ask_for_float64():
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300, check=True).stdout
    assert "after import: False float32" in out
    assert "error: Model: jaxhand computes in float64, which is off: call jaxhand.enable_x64() once" in out
    assert "after enable: float64 float64" in out


def test_the_cli_enables_float64_itself(tmp_path):
    code = "import sys; from jaxhand.cli import main; sys.exit(main(['models', 'index']))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "index: 3 DOF, 3 q entries" in out.stdout


def test_sync_dispatch_is_asked_for():
    flag = "jax.config.read('jax_cpu_enable_async_dispatch')"
    script = f"import jax, jaxhand as jh; a = {flag}; jh.enable_sync_dispatch(); print(a, {flag})"
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True).stdout
    assert out.split() == ["True", "False"]
