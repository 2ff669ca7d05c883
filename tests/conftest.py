"""Shared test setup: float64 and strict dtype promotion (no silent int -> float or float32 ->
float64 mixing); jaxtyping + beartype check every annotated jaxhand function (pyproject's
``--jaxtyping-packages``). Rank promotion stays allowed: (n, 3) + (3,) is how points and offsets
are written throughout."""

import jax

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402,F401
