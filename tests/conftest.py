"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision")."""

import jax

jax.config.update("jax_enable_x64", True)

import jaxhand  # noqa: E402,F401
