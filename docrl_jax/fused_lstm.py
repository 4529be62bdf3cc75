"""The LSTM actor's pass over sampled sequences as one Pallas kernel (`agent.lstm_kernel: pallas`).

An update runs the actor's LSTM over every sampled sequence step by step: the target actor over all
16 steps for the TD targets, the trained actor over the 8 burn-in steps before its loss. Traced by XLA
each step is a small matmul and a few element-wise kernels of a few microseconds each, one after the
other: dozens of launches per update that each do little. `sequence` runs all the steps of a block of
sequences in one kernel, the weights and the carry kept on chip, and returns the carry after each step.

It computes what `flax.linen.OptimizedLSTMCell` computes (the same parameters, gate order i, f, g, o,
the carry zeroed before a step whose reset flag is set, as `networks.unroll` does) but has no
gradient: it serves the passes whose gradient is stopped (burn-in, target actor); the trained steps
of the actor's loss stay with XLA. On a CPU the kernel runs in Pallas' interpreter (tests).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.experimental import pallas as pl
from jax.experimental.pallas import triton as plgpu

GATES = 4          # i, f, g, o: flax's OptimizedLSTMCell order and parameter names
BLOCK_ROWS = 64    # sequences per kernel instance (default)
_MIN_DIM = 16      # a GPU matmul tile's smallest side


def _pow2(n: int) -> int:
    return max(_MIN_DIM, 1 << (int(n) - 1).bit_length())


def applies(units: int) -> bool:
    """Whether `sequence` takes an LSTM of `units` hidden units (a power of two, >= 16); otherwise
    the trainer runs the steps with XLA."""
    return units >= _MIN_DIM and units == _pow2(units)


def _kernel(x_ref, keep_ref, c0_ref, h0_ref, wx_ref, wh_ref, b_ref, c_out, h_out):
    """One block of sequences, every step; refs: x [T, rows, D], keep [T, rows] (0 where the step
    resets the carry), c0/h0 [rows, U], wx [4, D, U], wh [4, U, U], b [4, U]; out [T, rows, U] each."""
    c, h = c0_ref[...], h0_ref[...]
    wx = [wx_ref[g] for g in range(GATES)]
    wh = [wh_ref[g] for g in range(GATES)]
    b = [b_ref[g][None, :] for g in range(GATES)]
    sigmoid = lambda z: 0.5 * jnp.tanh(0.5 * z) + 0.5  # noqa: E731  (exactly the logistic; tanh lowers everywhere)
    for t in range(x_ref.shape[0]):  # short sequences: unrolled, every index static
        keep = keep_ref[t][:, None]
        c, h = c * keep, h * keep
        x = x_ref[t]
        z = [jnp.dot(x, wx[g], preferred_element_type=jnp.float32)
             + jnp.dot(h, wh[g], preferred_element_type=jnp.float32) + b[g] for g in range(GATES)]
        c = sigmoid(z[1]) * c + sigmoid(z[0]) * jnp.tanh(z[2])
        h = sigmoid(z[3]) * jnp.tanh(c)
        c_out[t] = c
        h_out[t] = h


def _weights(lstm: dict, d_pad: int):
    """flax's per-gate Dense parameters as stacked matrices: wx [4, d_pad, U] (input rows zero-padded),
    wh [4, U, U], b [4, U]."""
    wx = jnp.stack([lstm[f"i{g}"]["kernel"] for g in "ifgo"]).astype(jnp.float32)
    wx = jnp.pad(wx, ((0, 0), (0, d_pad - wx.shape[1]), (0, 0)))
    wh = jnp.stack([lstm[f"h{g}"]["kernel"] for g in "ifgo"]).astype(jnp.float32)
    b = jnp.stack([lstm[f"h{g}"]["bias"] for g in "ifgo"]).astype(jnp.float32)
    return wx, wh, b


def sequence(lstm_params: dict, carry, obs_seq: jax.Array, reset_seq: jax.Array, interpret: bool | None = None,
             block_rows: int = BLOCK_ROWS, num_warps: int | None = None):
    """The LSTM over sequences, time on axis 0: `lstm_params` the cell's parameters
    (params["params"]["lstm"] of `networks.LSTMActor`), carry (c, h) [B, U], obs_seq [T, B, D],
    reset_seq [T, B] bool. Returns (c, h) after each step, [T, B, U] each (no gradient flows through).
    `interpret` defaults to Pallas' interpreter on a CPU; `block_rows` (sequences per kernel instance) and
    `num_warps` (Triton's, per instance) tune the GPU kernel."""
    c0, h0 = (jnp.asarray(x, jnp.float32) for x in carry)
    steps, rows, d = obs_seq.shape
    units = c0.shape[-1]
    if not applies(units):
        raise ValueError(f"fused_lstm.sequence needs a power-of-two LSTM width >= {_MIN_DIM}, not {units}")
    d_pad, t_pad = _pow2(d), 1 << (steps - 1).bit_length()
    b_pad = -(-rows // block_rows) * block_rows
    # Padded steps come after the real ones and padded rows are separate sequences: neither changes
    # the real outputs, which are sliced back out.
    x = jnp.pad(obs_seq.astype(jnp.float32), ((0, t_pad - steps), (0, b_pad - rows), (0, d_pad - d)))
    keep = jnp.pad(1.0 - reset_seq.astype(jnp.float32), ((0, t_pad - steps), (0, b_pad - rows)))
    c0, h0 = (jnp.pad(v, ((0, b_pad - rows), (0, 0))) for v in (c0, h0))
    wx, wh, b = _weights(lstm_params, d_pad)
    if interpret is None:
        interpret = jax.default_backend() == "cpu"
    seq_block = pl.BlockSpec((t_pad, block_rows, units), lambda i: (0, i, 0))
    c_seq, h_seq = pl.pallas_call(
        _kernel,
        grid=(b_pad // block_rows,),
        in_specs=[pl.BlockSpec((t_pad, block_rows, d_pad), lambda i: (0, i, 0)),
                  pl.BlockSpec((t_pad, block_rows), lambda i: (0, i)),
                  pl.BlockSpec((block_rows, units), lambda i: (i, 0)),
                  pl.BlockSpec((block_rows, units), lambda i: (i, 0)),
                  pl.BlockSpec((GATES, d_pad, units), lambda i: (0, 0, 0)),
                  pl.BlockSpec((GATES, units, units), lambda i: (0, 0, 0)),
                  pl.BlockSpec((GATES, units), lambda i: (0, 0))],
        out_specs=[seq_block, seq_block],
        out_shape=[jax.ShapeDtypeStruct((t_pad, b_pad, units), jnp.float32)] * 2,
        interpret=interpret,
        compiler_params=None if interpret else plgpu.CompilerParams(num_warps=num_warps, num_stages=1),
    )(*jax.lax.stop_gradient((x, keep, c0, h0, wx, wh, b)))
    return c_seq[:steps, :rows], h_seq[:steps, :rows]
