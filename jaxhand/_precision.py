"""jaxhand computes in float64, and asks for it explicitly instead of switching it on at import.

JAX's ``jax_enable_x64`` flag is global: turning it on changes the default dtype of every new
array in the whole program. So ``import jaxhand`` leaves it alone; :func:`enable_x64` turns it
on, and the entry points that build jaxhand's arrays (models, and with them everything else)
call :func:`require_x64`, which says in one line what to do when it is off.
"""

from __future__ import annotations

import os

import jax

from ._errors import InputError

__all__ = ["enable_x64", "enable_single_thread_cpu", "enable_sync_dispatch", "require_x64", "x64_enabled"]

#: XLA's CPU option that keeps Eigen's matrix kernels on the calling thread (XLA has no flag for the
#: intra-op pool itself, which jaxlib's LAPACK kernels still use for a large batch).
SINGLE_THREAD_XLA_FLAGS = ("--xla_cpu_multi_thread_eigen=false",)


def enable_x64() -> None:
    """Turn on JAX's float64 mode for the whole process (``jax_enable_x64``), which jaxhand needs:
    Jacobian checks against finite differences and cost tolerances of 1e-10 need double
    precision. Call it once, before building models or arrays; the CLI calls it itself."""
    jax.config.update("jax_enable_x64", True)


def enable_sync_dispatch() -> None:
    """Run JAX's CPU computations on the calling thread (``jax_cpu_enable_async_dispatch`` off) for
    the whole process: a tracker converts every small compiled call's result to NumPy at once, so
    handing each call to a worker thread and waiting only adds CPU time. Opt-in, like :func:`enable_x64`."""
    jax.config.update("jax_cpu_enable_async_dispatch", False)


def enable_single_thread_cpu() -> None:
    """Keep XLA's Eigen kernels on one thread (adds :data:`SINGLE_THREAD_XLA_FLAGS` to
    ``XLA_FLAGS``): a tracker's programs are too small to gain from a thread pool, whose hand-offs
    cost more than they save, and on one thread the results no longer depend on how the work was
    split. XLA reads the flags when JAX starts its CPU backend, so call this before the first JAX
    computation (importing jaxhand starts none); later it changes nothing. Opt-in for the whole
    process, like :func:`enable_x64`; the CLI calls it."""
    flags = os.environ.get("XLA_FLAGS", "").split()
    names = {f.split("=")[0] for f in flags}
    flags += [f for f in SINGLE_THREAD_XLA_FLAGS if f.split("=")[0] not in names]   # the user's own choice stays
    os.environ["XLA_FLAGS"] = " ".join(flags)


def x64_enabled() -> bool:
    """Whether JAX's float64 mode is on."""
    return bool(jax.config.jax_enable_x64)


def require_x64(where: str = "jaxhand") -> None:
    """Raise unless float64 is on.

    Raises:
        InputError: telling the user to call :func:`jaxhand.enable_x64` (or set JAX_ENABLE_X64=1).
    """
    if not x64_enabled():
        raise InputError(f"{where}: jaxhand computes in float64, which is off: call jaxhand.enable_x64() once at "
                         "the start of the program (or set JAX_ENABLE_X64=1); it turns on jax_enable_x64 for "
                         "the whole process")
