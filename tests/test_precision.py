"""float64 is asked for, not switched on at import (run in fresh interpreters: the tests' own
process has it on)."""

import os
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


def test_single_thread_cpu_adds_the_xla_flags_and_keeps_the_users():
    script = ("import os, jax.numpy as jnp, jaxhand as jh; "
              "jh.enable_single_thread_cpu(); jh.enable_single_thread_cpu(); "
              "print(os.environ['XLA_FLAGS']); print(float(jnp.ones((4, 4)).sum()))")
    env = {**os.environ, "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=true --xla_dump_to=/dev/null"}
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, check=True,
                         env=env).stdout.splitlines()
    assert out[0].split() == ["--xla_cpu_multi_thread_eigen=true", "--xla_dump_to=/dev/null"]
    assert out[1] == "16.0"


def test_the_cli_asks_for_one_thread_before_jax_starts():
    code = ("import os, sys; from jaxhand.cli import main; code = main(['models', 'index']); "
            "print(os.environ['XLA_FLAGS']); sys.exit(code)")
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1] == "--xla_cpu_multi_thread_eigen=false"
