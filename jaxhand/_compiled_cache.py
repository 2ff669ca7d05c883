"""A long-lived process keeps every program JAX compiled, and each compiled CPU program holds a
few memory maps. A process that compiles many kinds of problem (a test suite, a Dask worker that
runs jobs of many shapes) can reach the kernel's limit (``vm.max_map_count``, 65,530 by default),
where XLA's JIT fails ("Failed to materialize symbols") or corrupts memory.
:func:`release_compiled` drops the compiled programs before that.
"""

from __future__ import annotations

import gc
from pathlib import Path

import jax

__all__ = ["memory_maps", "release_compiled"]

_MAPS = Path("/proc/self/maps")
_MAP_LIMIT = Path("/proc/sys/vm/max_map_count")


def memory_maps() -> tuple[int, int] | None:
    """(memory maps this process holds, the kernel's limit), or None where ``/proc`` does not
    tell (not Linux)."""
    try:
        with _MAPS.open() as maps:
            held = sum(1 for _ in maps)
        return held, int(_MAP_LIMIT.read_text())
    except (OSError, ValueError):
        return None


def release_compiled(share: float = 0.5) -> bool:
    """Drop JAX's compiled programs (``jax.clear_caches``) when this process holds more than
    ``share`` of the kernel's memory-map limit; the next call of each program compiles it again.
    Returns whether it dropped them."""
    maps = memory_maps()
    if maps is None or maps[0] <= share * maps[1]:
        return False
    jax.clear_caches()
    gc.collect()
    return True
