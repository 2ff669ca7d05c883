"""Shared test setup: float64 (jaxhand enables it on import)."""

import jaxhand  # noqa: F401  (enables float64)
