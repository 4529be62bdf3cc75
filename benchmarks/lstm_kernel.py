"""The LSTM actor's stopped-gradient pass over sampled sequences: XLA step by step (`networks.unroll`)
against one Pallas kernel (`fused_lstm.sequence`), on this machine's default device.

    python benchmarks/lstm_kernel.py --out OUT [--batch 1024] [--steps 16 8] [--repeats 5]

For each sequence length: the largest difference between the two passes' carries (random parameters
and observations, ~15 % of the steps resetting the carry), the compile time, and the median over
`--repeats` calls of the time of one pass (each call runs `--passes` passes in a jitted scan).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax import fused_lstm
from docrl_jax.envs import OBS_SIZE
from docrl_jax.networks import LSTMActor, unroll

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import run_meta, write_results  # noqa: E402


TITLE = "The LSTM's stopped-gradient pass: XLA step by step against one Pallas kernel"
COLUMNS = [("kernel", "kernel"), ("batch", "batch"), ("steps", "steps"), ("compile s", "compile_s"),
           ("ms per pass", "ms_per_pass"), ("largest difference from XLA's carries", "max_abs_diff_vs_xla")]


def inputs(batch: int, steps: int, units: int):
    k = jax.random.split(jax.random.PRNGKey(0), 6)
    actor = LSTMActor(units)
    obs = jax.random.normal(k[0], (steps, batch, OBS_SIZE))
    reset = jax.random.uniform(k[1], (steps, batch)) < 0.15
    params = actor.init(k[2], actor.init_carry((batch,)), obs[0])
    params = jax.tree.map(lambda x: x + 0.2 * jax.random.normal(k[3], x.shape), params)
    carry = (jax.random.normal(k[4], (batch, units)), jax.random.normal(k[5], (batch, units)))
    return actor, params, carry, obs, reset


def timed(fn, args, passes: int, repeats: int) -> tuple[float, float]:
    """(compile s, median ms per pass) of `fn(*args)` run `passes` times in a scan."""
    def many(args):
        def body(c, _):
            out = fn(*args)
            return c + jnp.sum(out[1][-1]), None  # depends on every pass's last carry
        return jax.lax.scan(body, jnp.zeros(()), None, length=passes)[0]
    t0 = time.perf_counter()
    compiled = jax.jit(many).lower(args).compile()
    compile_s = time.perf_counter() - t0
    compiled(args).block_until_ready()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        compiled(args).block_until_ready()
        times.append((time.perf_counter() - t0) * 1e3 / passes)
    return compile_s, statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--batch", type=int, default=1024)
    ap.add_argument("--steps", type=int, nargs="+", default=[16, 8])
    ap.add_argument("--units", type=int, default=32)
    ap.add_argument("--passes", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--block-rows", type=int, nargs="+", default=[fused_lstm.BLOCK_ROWS],
                    help="the kernel's sequences per instance (one row per value and warp count)")
    ap.add_argument("--warps", type=int, nargs="+", default=[0], help="Triton warps per instance (0: Triton's default)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    args = ap.parse_args()
    rows, meta = [], run_meta()
    for steps in args.steps:
        actor, params, carry, obs, reset = inputs(args.batch, steps, args.units)

        def xla(p, c, o, r):
            _, _, _, after = unroll(actor, p, c, o, r, True)
            return after

        want = jax.jit(xla)(params, carry, obs, reset)
        variants = [("xla", xla)]
        for rows_per, warps in [(b, w) for b in args.block_rows for w in args.warps]:
            variants.append((f"pallas {rows_per} rows, {warps or 'default'} warps",
                             lambda p, c, o, r, b=rows_per, w=warps: fused_lstm.sequence(
                                 p["params"]["lstm"], c, o, r, block_rows=b, num_warps=w or None)))
        for name, fn in variants:
            got = jax.jit(fn)(params, carry, obs, reset)
            diff = max(float(jnp.max(jnp.abs(a - b))) for a, b in zip(want, got))
            compile_s, ms = timed(fn, (params, carry, obs, reset), args.passes, args.repeats)
            rows.append({"kernel": name, "batch": args.batch, "steps": steps, "compile_s": round(compile_s, 2),
                         "ms_per_pass": round(ms, 4), "max_abs_diff_vs_xla": diff})
            print(rows[-1], flush=True)
            write_results(args.out, "lstm_kernel", TITLE, meta, rows, COLUMNS)


if __name__ == "__main__":
    main()
