"""The cost of one gradient update, in isolation, across recipe and precision variants.

    python benchmarks/update_cost.py --config td3_lstm --out benchmarks/results/h100/update_cost
    python benchmarks/update_cost.py --variant "b4096|default|replay.batch_size=4096"

Each variant is `label|precision|override;override...`: the agent of `--config` with those overrides
(`section.key=value`, as `--set` takes them), traced under `jax.default_matmul_precision(precision)`
("default" leaves JAX's default). Its `agent.update` runs `--updates` times inside one jitted scan on
one fixed, well-formed batch of random sequences (the shapes `replay.sample` returns; the values do
not change the work), at a fixed training progress; the table reports the median over `--repeats`
calls of ms per update, compile time separately, and trained samples per ms (batch x trained steps).
Which updates run the delayed actor follows the config's `agent.policy_freq` (0: the paper's
schedule, every 2nd update at progress 0); `agent.policy_freq=1` times critic + actor on every update.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import jax
import jax.numpy as jnp

from docrl_jax.algorithms import make_agent
from docrl_jax.config import load_config
from docrl_jax.envs import ACTION_SIZE, OBS_SIZE

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import run_meta, write_results  # noqa: E402

DEFAULT_VARIANTS = (
    "default|default|",
    "tf32|tensorfloat32|",
    "fp32|float32|",
    "bf16|bfloat16|",
    "actor every update|default|agent.policy_freq=1",
    "critic only|default|agent.policy_freq=1000000",
    "b256|default|replay.batch_size=256",
    "b2048|default|replay.batch_size=2048",
    "b4096|default|replay.batch_size=4096",
    "b4096 bf16|bfloat16|replay.batch_size=4096",
    "b8192 bf16|bfloat16|replay.batch_size=8192",
    "no burn-in (seq 8)|default|replay.seq_len=8;replay.burn_in=0",
    "critics 256x256|default|agent.critic_hidden=[256,256]",
    "MLP actor|default|agent.actor=mlp;agent.actor_hidden=[256,256];agent.memory=false;replay.burn_in=0;replay.seq_len=8",
)


def random_batch(config, agent, key) -> dict:
    """A batch shaped as `SequenceBuffer.sample` returns it: [batch, seq_len, ...]."""
    b, l = config.replay.batch_size, config.replay.seq_len
    ks = jax.random.split(key, 6)
    carry = jax.tree.map(lambda z: 0.1 * jax.random.normal(ks[5], z.shape), agent.actor.init_carry((b, l)))
    start = jax.random.uniform(ks[3], (b, l)) < 0.01
    return {"obs": jax.random.normal(ks[0], (b, l, OBS_SIZE)),
            "action": jax.random.uniform(ks[1], (b, l, ACTION_SIZE), minval=-1.0, maxval=1.0),
            "reward": jax.random.normal(ks[2], (b, l)), "next_obs": jax.random.normal(ks[4], (b, l, OBS_SIZE)),
            "terminated": jax.random.uniform(ks[4], (b, l)) < 0.005, "truncated": jnp.zeros((b, l), bool),
            "start": start, "carry": carry, "mask": jnp.cumsum(start.at[:, 0].set(False), axis=1) == 0}


def measure(config_name: str, variant: str, updates: int, repeats: int, progress: float) -> dict:
    label, precision, sets = variant.split("|")
    overrides = [s for s in sets.split(";") if s]
    config = load_config(config_name, overrides)
    agent = make_agent(config)
    key = jax.random.PRNGKey(0)
    state = jax.jit(agent.init)(key)
    batch = jax.jit(lambda k: random_batch(config, agent, k))(key)

    def run(state, batch, key):
        def one(s, k):
            s, m = agent.update(s, batch, k, jnp.float32(progress))
            return s, m["critic_loss"]
        return jax.lax.scan(one, state, jax.random.split(key, updates))

    t0 = time.perf_counter()
    if precision == "default":
        compiled = jax.jit(run).lower(state, batch, key).compile()
    else:
        with jax.default_matmul_precision(precision):
            compiled = jax.jit(run).lower(state, batch, key).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(state, batch, key))
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        out = compiled(state, batch, jax.random.PRNGKey(i + 1))
        jax.block_until_ready(out)
        times.append(time.perf_counter() - t0)
    ms = 1e3 * statistics.median(times) / updates
    trained = config.replay.batch_size * (config.replay.seq_len - config.replay.burn_in)
    return {"variant": label, "precision": precision, "overrides": overrides, "batch_size": config.replay.batch_size,
            "seq_len": config.replay.seq_len, "burn_in": config.replay.burn_in, "compile_s": round(compile_s, 2),
            "ms_per_update": round(ms, 4), "ms_all": [round(1e3 * t / updates, 4) for t in times],
            "trained_samples_per_ms": round(trained / ms), "finite": bool(jnp.all(jnp.isfinite(out[1])))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--variant", action="append", help="label|precision|overrides (repeatable; default: a grid)")
    ap.add_argument("--updates", type=int, default=50, help="updates per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--progress", type=float, default=0.0, help="training progress the updates see (schedules)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--stem", default="update_cost")
    args = ap.parse_args(argv)
    meta, rows = run_meta(), []
    cols = [("variant", "variant"), ("precision", "precision"), ("batch", "batch_size"), ("seq", "seq_len"),
            ("compile s", "compile_s"), ("ms / update", "ms_per_update"), ("trained samples / ms", "trained_samples_per_ms"),
            ("finite", "finite")]
    for v in args.variant or DEFAULT_VARIANTS:
        rows.append(measure(args.config, v, args.updates, args.repeats, args.progress))
        table = write_results(args.out, args.stem, f"One update of {args.config}", meta, rows, cols)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
