"""The private JAX names the program store relies on (docrl_jax/train/jax_internals.py): a JAX upgrade that
moves one fails here, naming it, instead of every launch silently compiling again."""

import jax
import numpy as np
import pytest

from docrl_jax.train import jax_internals


def test_every_private_name_the_store_uses_is_in_this_jax():
    assert jax_internals.missing() == []
    assert jax_internals.cpu_kernels_ready()


def test_a_program_written_and_read_back_computes_the_same():
    table = np.arange(5, dtype=np.float32)
    compiled = jax.jit(lambda x, y: (x * table, y.sum())).lower(np.ones(5, np.float32), np.ones(3)).compile()
    payload, in_tree, out_tree = jax_internals.dumps(compiled)
    program = jax_internals.callable_program(jax_internals.unpack(payload, jax.devices()[:1]), in_tree, out_tree)
    x, y = np.linspace(0, 1, 5, dtype=np.float32), np.full(3, 2.0)
    for got, want in zip(program(x, y), compiled(x, y)):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))


def test_parts_whose_constants_are_not_the_executables_are_refused():
    compiled = jax.jit(lambda x: x + 1.0).lower(np.ones(2, np.float32)).compile()
    payload, in_tree, out_tree = jax_internals.dumps(compiled)
    *parts, consts = jax_internals.unpack(payload, jax.devices()[:1])
    changed = jax_internals.unpack(jax_internals.pack((*parts, [*consts, np.zeros(3, np.float32)])), jax.devices()[:1])
    with pytest.raises(LookupError, match="inputs are not the entry's"):
        jax_internals.callable_program(changed, in_tree, out_tree)
