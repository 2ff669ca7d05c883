"""release_compiled: compiled programs hold memory maps, and dropping them gives the maps back."""

import jax
import jax.numpy as jnp
import pytest

import jaxhand


def test_dropping_the_compiled_programs_gives_their_memory_maps_back():
    if jaxhand.memory_maps() is None:
        pytest.skip("no /proc: memory maps are not counted here")
    x = jnp.ones(3)
    programs = [jax.jit(lambda v, k=k: jnp.sin(v) * k + jnp.cos(v)) for k in range(60)]
    held0, limit = jaxhand.memory_maps()
    for f in programs:
        f(x).block_until_ready()
    held1 = jaxhand.memory_maps()[0]
    assert held1 - held0 >= 60   # about three per compiled CPU program
    assert limit > held1
    assert not jaxhand.release_compiled(1.0)   # under the limit: nothing dropped
    assert jaxhand.memory_maps()[0] >= held1
    assert jaxhand.release_compiled(0.0)
    assert jaxhand.memory_maps()[0] <= held1 - 60
    assert float(programs[0](x)[0]) == pytest.approx(float(jnp.cos(1.0)))   # compiles again
