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

`--trace DIR` also runs one more call of each variant under `jax.profiler.trace` (a Perfetto trace
per variant in DIR) and reads the device's kernels from it: how many launch per update, how long the
device is busy per update against the wall time per update (the rest is time between kernels), and
the kernels that take the most time and the time of each kind of kernel (matmuls, reductions,
transposes, copies, other fusions: `<stem>_kernels.md`). Every variant also counts the fusions and
library calls in its compiled program (`hlo_kernels`: the whole scan, an upper bound on the kernels
one update launches).
"""

from __future__ import annotations

import argparse
import collections
import glob
import gzip
import json
import os
import re
import statistics
import time

import jax
import jax.numpy as jnp

from docrl_jax.algorithms import make_agent
from docrl_jax.config import load_config
from docrl_jax.envs import ACTION_SIZE, OBS_SIZE

from docrl_jax.benchmarking import run_meta, write_results

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


def device_kernels(trace_dir: str) -> tuple[list[dict], dict]:
    """The kernel events of the device timelines in the Perfetto trace under `trace_dir`: complete
    events of the processes named after a GPU, on their stream lines (not the derived "XLA Ops" /
    "XLA Modules" lines, which overlap the kernels); and every line of those processes with its event
    count and total microseconds, to read the trace by when its lines are named otherwise."""
    path = sorted(glob.glob(os.path.join(trace_dir, "**", "perfetto_trace.json.gz"), recursive=True))[-1]
    with gzip.open(path, "rt") as f:
        events = json.load(f)["traceEvents"]
    procs = {e["pid"]: e["args"]["name"] for e in events if e.get("ph") == "M" and e.get("name") == "process_name"}
    threads = {(e["pid"], e["tid"]): e["args"]["name"] for e in events
               if e.get("ph") == "M" and e.get("name") == "thread_name"}
    gpu = {pid for pid, name in procs.items() if "GPU" in name or "gpu" in name}
    device = [e for e in events if e.get("ph") == "X" and e["pid"] in gpu]
    lines = collections.defaultdict(lambda: [0, 0.0])
    for e in device:
        line = lines[f"{procs[e['pid']]} / {threads.get((e['pid'], e['tid']), e['tid'])}"]
        line[0] += 1
        line[1] += e["dur"]
    return [e for e in device if "stream" in threads.get((e["pid"], e["tid"]), "").lower()], dict(lines)


# What a kernel does, read from the name XLA or the library gave it (first pattern that matches).
KERNEL_KINDS = (("matmul", r"gemm|nvjet|cutlass|xmma|cublas|dot"), ("reduction", r"reduce"),
                ("transpose", r"transpose"), ("copy", r"copy|memcpy|memset|dynamic.update.slice|slice"),
                ("elementwise", r"loop_|fusion"))


def kernel_kind(name: str) -> str:
    return next((kind for kind, pattern in KERNEL_KINDS if re.search(pattern, name)), "other")


def kernel_summary(kernels: list[dict], updates: int, wall_ms: float, top: int = 15) -> dict:
    """Calls and device time per update of every kernel (`all`), of the `top` ones, and of each kind of
    kernel (`kinds`: how many launch and how long they take, where a fused update would save)."""
    by_name = collections.defaultdict(lambda: [0, 0.0])
    for k in kernels:
        by_name[k["name"]][0] += 1
        by_name[k["name"]][1] += k["dur"]
    busy_us = sum(v[1] for v in by_name.values())

    def row(n, c, t):
        return {"kernel": n[:90], "calls_per_update": round(c / updates, 2), "us_per_update": round(t / updates, 2),
                "share_of_busy": round(t / busy_us, 3) if busy_us else None}
    ranked = sorted(by_name.items(), key=lambda kv: -kv[1][1])
    kinds = collections.defaultdict(lambda: [0, 0.0])
    for n, (c, t) in ranked:
        kind = kinds[kernel_kind(n)]
        kind[0] += c
        kind[1] += t
    return {"kernels_per_update": round(len(kernels) / updates, 1),
            "busy_ms_per_update": round(busy_us / 1e3 / updates, 4), "wall_ms_per_update": round(wall_ms, 4),
            "top": [row(n, c, t) for n, (c, t) in ranked[:top]],
            "kinds": [{**row(kind, c, t), "us_per_call": round(t / c, 2) if c else None}
                      for kind, (c, t) in sorted(kinds.items(), key=lambda kv: -kv[1][1])],
            "all": [row(n, c, t) for n, (c, t) in ranked]}


def measure(config_name: str, variant: str, updates: int, repeats: int, progress: float,
            trace_dir: str | None = None) -> dict:
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
    hlo = compiled.as_text()
    extra = {"hlo_kernels": len(re.findall(r"= \S+ (?:fusion|custom-call)\(", hlo))}
    if trace_dir is not None:
        where = os.path.join(trace_dir, re.sub(r"\W+", "_", label))
        with jax.profiler.trace(where, create_perfetto_trace=True):
            jax.block_until_ready(compiled(state, batch, jax.random.PRNGKey(repeats + 1)))
        kernels, lines = device_kernels(where)
        extra["kernels"] = {**kernel_summary(kernels, updates, ms), "device_lines": lines}
    return {**extra, "variant": label, "precision": precision, "overrides": overrides, "batch_size": config.replay.batch_size,
            "seq_len": config.replay.seq_len, "burn_in": config.replay.burn_in, "compile_s": round(compile_s, 2),
            "ms_per_update": round(ms, 4), "ms_all": [round(1e3 * t / updates, 4) for t in times],
            "trained_samples_per_ms": round(trained / ms), "finite": bool(jnp.all(jnp.isfinite(out[1])))}


def write_kernel_tables(out: str, stem: str, config: str, rows: list[dict]) -> None:
    lines = [f"# Kernels of one update of {config} (from a profiler trace of one call per variant)", ""]
    for r in rows:
        k = r["kernels"]
        lines += [f"## {r['variant']}", "",
                  f"{k['kernels_per_update']} kernels per update; the device busy {k['busy_ms_per_update']} ms of "
                  f"{k['wall_ms_per_update']} ms per update (timed calls); {r['hlo_kernels']} fusions and library "
                  "calls in the compiled scan", "", "| kernel | calls / update | us / update | share of busy |",
                  "|---|---|---|---|"]
        lines += [f"| `{t['kernel']}` | {t['calls_per_update']} | {t['us_per_update']} | {t['share_of_busy']} |"
                  for t in k["top"]] + [""]
        lines += ["By kind (`KERNEL_KINDS`; every kernel is in the JSON's `kernels.all`):", "",
                  "| kind | calls / update | us / update | us / call | share of busy |", "|---|---|---|---|---|"]
        lines += [f"| {t['kernel']} | {t['calls_per_update']} | {t['us_per_update']} | {t['us_per_call']} | "
                  f"{t['share_of_busy']} |" for t in k["kinds"]] + [""]
    with open(os.path.join(out, f"{stem}_kernels.md"), "w") as f:
        f.write("\n".join(lines))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--variant", action="append", help="label|precision|overrides (repeatable; default: a grid)")
    ap.add_argument("--updates", type=int, default=50, help="updates per timed call")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--progress", type=float, default=0.0, help="training progress the updates see (schedules)")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "results"))
    ap.add_argument("--stem", default="update_cost")
    ap.add_argument("--trace", metavar="DIR", help="also profile one call per variant and tabulate its kernels")
    args = ap.parse_args(argv)
    meta, rows = run_meta(), []
    cols = [("variant", "variant"), ("precision", "precision"), ("batch", "batch_size"), ("seq", "seq_len"),
            ("compile s", "compile_s"), ("ms / update", "ms_per_update"), ("trained samples / ms", "trained_samples_per_ms"),
            ("kernels in the program", "hlo_kernels"), ("finite", "finite")]
    for v in args.variant or DEFAULT_VARIANTS:
        rows.append(measure(args.config, v, args.updates, args.repeats, args.progress, args.trace))
        table = write_results(args.out, args.stem, f"One update of {args.config}", meta, rows, cols)
        if args.trace:
            write_kernel_tables(args.out, args.stem, args.config, rows)
    print(table)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
