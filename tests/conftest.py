"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision") and
strict dtype promotion, so an implicit int/float or float32/float64 mix in jnp code fails here.
Rank promotion stays allowed. pytest also checks the package's annotations at run time
(``--jaxtyping-packages`` in pyproject, with the checker of ``typecheck.py``).

The suite builds thousands of small XLA programs and runs most of them a few times, so it asks
LLVM for no optimisation (``--xla_backend_optimization_level=0``, for the workers and the
subprocesses they start): compiling, not running, is most of its time. Only rounding changes;
the benchmarks and the package keep XLA's default."""

import os

_XLA_FLAG = "--xla_backend_optimization_level=0"
if _XLA_FLAG.split("=")[0] not in os.environ.get("XLA_FLAGS", ""):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} {_XLA_FLAG}".strip()

import jax  # noqa: E402
import pytest  # noqa: E402

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test module, drop JAX's compiled programs once the worker holds half the kernel's
    memory maps (a whole suite's programs reached 63,342 of 65,530 in one worker: jaxhand.release_compiled)."""
    yield
    jaxhand.release_compiled(0.5)
