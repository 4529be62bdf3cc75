"""The LSTM's one-kernel pass (docrl_jax/fused_lstm.py, Pallas' interpreter on the CPU) against XLA's
step-by-step pass (networks.unroll)."""

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax import fused_lstm
from docrl_jax.networks import LSTMActor, unroll


def test_kernel_carries_match_the_step_by_step_pass_with_resets_and_padding():
    actor = LSTMActor(32)
    k = jax.random.split(jax.random.PRNGKey(0), 6)
    steps, rows = 11, 70   # neither a power of two nor a whole block: both are padded
    obs = jax.random.normal(k[0], (steps, rows, 26))
    reset = jax.random.uniform(k[1], (steps, rows)) < 0.2
    params = actor.init(k[2], actor.init_carry((rows,)), obs[0])
    params = jax.tree.map(lambda x: x + 0.3 * jax.random.normal(k[3], x.shape), params)  # non-zero biases too
    carry = (jax.random.normal(k[4], (rows, 32)), jax.random.normal(k[5], (rows, 32)))
    _, _, _, after = unroll(actor, params, carry, obs, reset, True)
    c_seq, h_seq = fused_lstm.sequence(params["params"]["lstm"], carry, obs, reset, interpret=True)
    np.testing.assert_allclose(np.asarray(c_seq), np.asarray(after[0]), atol=1e-5)
    np.testing.assert_allclose(np.asarray(h_seq), np.asarray(after[1]), atol=1e-5)
    assert not fused_lstm.applies(24) and fused_lstm.applies(32)
