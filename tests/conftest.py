"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision") and
strict dtype promotion, so an implicit int/float or float32/float64 mix in jnp code fails here.
Rank promotion stays allowed. pytest also checks the package's annotations at run time
(``--jaxtyping-packages`` in pyproject, with the checker of ``typecheck.py``)."""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402,F401
