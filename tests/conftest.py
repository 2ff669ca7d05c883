"""Shared test setup: float64 (jaxhand needs it; see the README's "Conventions and precision") and
strict dtype promotion, so an implicit int/float or float32/float64 mix in jnp code fails here.
Rank promotion stays allowed. pytest also checks the package's annotations at run time
(``--jaxtyping-packages`` in pyproject, with the checker of ``typecheck.py``).

One JAX persistent compilation cache serves the whole run: many tests build trackers and fits of
the same structure in other workers or in subprocesses (CLI runs, notebooks), and each would
otherwise compile the same programs again."""

import os
import shutil
import tempfile

import jax
import pytest

jax.config.update("jax_enable_x64", True)
jax.config.update("jax_numpy_dtype_promotion", "strict")

import jaxhand  # noqa: E402

_CACHE_ENV = "JAX_COMPILATION_CACHE_DIR"
_OWN_CACHE = pytest.StashKey[str]()   # the folder this run made (absent where the caller set one)


def pytest_configure(config):
    """The controller (or a run without xdist) makes the run's cache folder; workers and
    subprocesses inherit it through the environment. A cache the caller set is left alone."""
    if hasattr(config, "workerinput") or os.environ.get(_CACHE_ENV):
        return
    os.environ[_CACHE_ENV] = config.stash[_OWN_CACHE] = tempfile.mkdtemp(prefix="jaxhand-tests-jit-")
    jax.config.update("jax_compilation_cache_dir", os.environ[_CACHE_ENV])


def pytest_unconfigure(config):
    """The run's own cache folder is removed at the end."""
    path = config.stash.get(_OWN_CACHE, None)
    if path:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After a test module, drop JAX's compiled programs once the worker holds half the kernel's
    memory maps (a whole suite's programs reached 63,342 of 65,530 in one worker: jaxhand.release_compiled)."""
    yield
    jaxhand.release_compiled(0.5)
