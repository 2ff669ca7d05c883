"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision") and
strict dtype promotion, so an implicit int/float or float32/float64 mix in jnp code fails here.
Rank promotion stays allowed. pytest also checks the package's annotations at run time
(``--jaxtyping-packages`` in pyproject, with the checker of ``typecheck.py``)."""

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test module, drop JAX's compiled programs once the worker holds half the kernel's
    memory maps (a whole suite's programs reached 63,342 of 65,530 in one worker: jaxhand.release_compiled)."""
    yield
    jaxhand.release_compiled(0.5)
