"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision") and
strict dtype promotion, so an implicit int/float or float32/float64 mix in jnp code fails here.
Rank promotion stays allowed. pytest also checks the package's annotations at run time
(``--jaxtyping-packages`` in pyproject, with the checker of ``typecheck.py``)."""

import gc
from pathlib import Path

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402,F401

_MAPS = Path("/proc/self/maps")
_MAP_LIMIT = Path("/proc/sys/vm/max_map_count")


def _memory_maps() -> tuple[int, int]:
    """(memory maps this process holds, the kernel's limit), or (0, 1) where /proc is missing."""
    if not (_MAPS.exists() and _MAP_LIMIT.exists()):
        return 0, 1
    with _MAPS.open() as maps:
        return sum(1 for _ in maps), int(_MAP_LIMIT.read_text())


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test module, drop JAX's compiled programs once the process holds half the kernel's
    memory maps: each compiled CPU program holds about three, and a worker that keeps a whole
    suite's programs reaches vm.max_map_count (65530), where XLA's JIT fails ("Failed to
    materialize symbols") or corrupts memory."""
    yield
    held, limit = _memory_maps()
    if held > limit // 2:
        jax.clear_caches()
        gc.collect()
