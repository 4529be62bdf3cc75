"""The benchmark shelf: what the scripts in `benchmarks/` measure again and again, in one tested place.

- the facts recorded with every result (`run_meta`: command, GPU, device, date, versions) and the result
  files (`write_results`: a JSON of the rows and a Markdown table, rewritten after every row);
- throughput: `time_chunks` (warm calls of a compiled training chunk), `chunk_steps_per_s` (from a
  trainer's `--no-progress` log);
- time to success: `read_rows` (a run's metrics.csv), `reached` (the first evaluation at a target both
  ways), the run goal (`GOAL`, `meets_goal`, `goal_counts`) and its table cells (`pct`, `pair`);
- a GPU job's packs unpacked (`unpack`);
- the peers' published recipes (`PEER_RECIPES`, `peer_recipe`: Brax and MuJoCo Playground).

Light at import (no JAX until a function needs it), so a table script runs without a GPU.
"""

from __future__ import annotations

import csv
import datetime as dt
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import tarfile
import time
from importlib.metadata import version
from pathlib import Path

# ---------------------------------------------------------------------------------------------- run facts

VERSIONED = ("jax", "jaxlib", "mujoco", "mujoco-mjx", "flax", "optax", "orbax-checkpoint")


def gpu_name() -> str:
    """The first GPU's name as nvidia-smi gives it, or "none"."""
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=20)
        return out.stdout.strip().splitlines()[0] if out.returncode == 0 and out.stdout.strip() else "none"
    except (OSError, subprocess.TimeoutExpired):
        return "none"


def run_meta() -> dict:
    """What every result records: the command line, the GPU, JAX's first device, the UTC date and the
    versions of Python and of `VERSIONED`."""
    import jax
    return {"command": " ".join([os.path.basename(sys.executable)] + sys.argv), "gpu": gpu_name(),
            "device": str(jax.devices()[0]), "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
            "versions": {"python": platform.python_version(), **{p: version(p) for p in VERSIONED}}}


def write_results(out_dir: str, stem: str, title: str, meta: dict, rows: list[dict],
                  columns: list[tuple[str, str]]) -> str:
    """Writes <stem>.json (meta + rows) and <stem>.md (a table of `columns`: (header, row key)); returns the
    table. Called after every row, so a sweep that fails part-way keeps what it measured."""
    os.makedirs(out_dir, exist_ok=True)
    with open(os.path.join(out_dir, f"{stem}.json"), "w") as f:
        json.dump({**meta, "results": rows}, f, indent=1)
    fmt = lambda v: f"{v:,}" if isinstance(v, int) and not isinstance(v, bool) else str(v)
    lines = [f"# {title} ({meta['gpu']}, {meta['date']})", "", f"Command: `{meta['command']}`  ",
             f"Versions: {meta['versions']}", "", "| " + " | ".join(h for h, _ in columns) + " |",
             "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(fmt(r[k]) for _, k in columns) + " |" for r in rows]
    table = "\n".join(lines) + "\n"
    with open(os.path.join(out_dir, f"{stem}.md"), "w") as f:
        f.write(table)
    return table

# --------------------------------------------------------------------------------------------- throughput


def time_chunks(chunk, state, repeats: int, get=lambda tree: tree):
    """One warm-up call of the compiled `chunk` (it fills the buffer, so every later iteration learns),
    then `repeats` timed calls. Returns (state, seconds of each call, the fewest learning iterations
    of any seed in each: `get` brings a call's metrics to the host)."""
    import jax
    import numpy as np
    state, m = chunk(state)
    jax.block_until_ready(m)
    times, learn = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        state, m = chunk(state)
        jax.block_until_ready(m)
        times.append(time.perf_counter() - t0)
        learn.append(int(np.min(get(m["learn_iters"]))))
    return state, times, learn


def env_throughput(scenario: int, num_envs: int, steps: int, repeats: int, variant: str, unroll: int | None = None,
                   overrides: dict | None = None) -> dict:
    """Control steps/s of `num_envs` envs of `scenario` (env overrides `overrides`) stepped with random
    actions in one compiled scan of `steps` steps (auto-reset when `variant` is "autoreset"): the median of
    `repeats` calls after a warm-up, with the compile time."""
    import jax

    import docrl_jax.envs as envs
    env = envs.make(scenario, auto_reset=(variant == "autoreset"), substep_unroll=unroll, **(overrides or {}))
    reset = jax.jit(jax.vmap(env.reset))

    def rollout(state, key):
        def body(s, k):
            a = jax.random.uniform(k, (num_envs, 3), minval=-1.0, maxval=1.0)
            s = jax.vmap(env.step)(s, a)
            return s, s.reward.sum()
        state, rewards = jax.lax.scan(body, state, jax.random.split(key, steps))
        return state, rewards.sum()

    state = reset(jax.random.split(jax.random.PRNGKey(0), num_envs))
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    compiled = jax.jit(rollout, donate_argnums=0).lower(state, jax.random.PRNGKey(1)).compile()
    compile_s = time.perf_counter() - t0
    state, _ = compiled(state, jax.random.PRNGKey(2))  # warm-up
    jax.block_until_ready(state)
    times = []
    for r in range(repeats):
        t0 = time.perf_counter()
        state, total = compiled(state, jax.random.PRNGKey(3 + r))
        jax.block_until_ready(total)
        times.append(time.perf_counter() - t0)
    med = statistics.median(times)
    sps = num_envs * steps / med
    return {"scenario": scenario, "env": overrides or {}, "variant": variant, "substep_unroll": env.substep_unroll, "num_envs": num_envs, "steps_per_call": steps,
            "repeats": repeats, "compile_s": round(compile_s, 2), "call_s_median": round(med, 5),
            "call_s_all": [round(t, 5) for t in times], "control_steps_per_s": round(sps),
            "sim_seconds_per_s": round(sps * env.control_dt),
            "physics_steps_per_s": round(sps * env.params.substeps)}


def train_throughput(name: str, num_envs: int, iters: int, repeats: int, sets: list[str]) -> dict:
    """Env steps/s and gradient updates/s of config `name`'s compiled training chunk at `num_envs` envs,
    `iters` iterations a chunk, every one learning (`time_chunks`), `sets` (`--set` strings) applied."""
    import jax

    from docrl_jax.config import load_config
    from docrl_jax.train import make_trainer
    # 128 steps of history per env (the default 50,000 transitions hold only 12 at 4,096 envs).
    overrides = [f"env.num_envs={num_envs}", f"train.log_every={num_envs * iters}", "train.start_steps=0",
                 "train.num_seeds=1", *sets]
    if load_config(name).replay.buffer_size < 128 * num_envs:
        overrides.insert(4, f"replay.buffer_size={128 * num_envs}")
    config = load_config(name, overrides)
    trainer = make_trainer(config)
    state = jax.jit(trainer.init)(jax.random.PRNGKey(0))
    jax.block_until_ready(state)
    t0 = time.perf_counter()
    chunk = jax.jit(trainer.chunk, donate_argnums=0).lower(state).compile()
    compile_s = time.perf_counter() - t0
    state, times, learn = time_chunks(chunk, state, repeats)
    med = statistics.median(times)
    stats = jax.devices()[0].memory_stats() or {}
    upd = config.train.updates_per_step
    trained = config.replay.seq_len - config.replay.burn_in
    return {"config": name, "algo": config.agent.algo, "num_envs": num_envs, "iters_per_chunk": trainer.iters_per_chunk,
            "updates_per_step": upd, "batch_size": config.replay.batch_size, "seq_len": config.replay.seq_len,
            "compile_s": round(compile_s, 2), "chunk_s_median": round(med, 4), "chunk_s_all": [round(t, 4) for t in times],
            "learning_iters_per_chunk": learn, "env_steps_per_s": round(trainer.steps_per_chunk / med),
            "grad_updates_per_s": round(trainer.iters_per_chunk * upd / med, 1),
            "trained_steps_per_update": config.replay.batch_size * trained,
            "trained_samples_per_s": round(trainer.iters_per_chunk * upd * config.replay.batch_size * trained / med),
            "peak_gpu_memory_gib": round(stats.get("peak_bytes_in_use", 0) / 2**30, 3) if stats else None,
            "overrides": overrides}


def chunk_steps_per_s(log: str) -> float:
    """Median env steps/s of the chunks that learned on every iteration in a trainer's `--no-progress` log
    (the lines that give an ETA), evaluations excluded."""
    with open(log) as f:
        rates = [float(m.group(1).replace(",", "")) for line in f
                 if "ETA" in line and "once learning" not in line
                 for m in [re.match(r"[\d,]+ steps\s+([\d,]+) steps/s", line)] if m]
    return statistics.median(rates)

# -------------------------------------------------------------------------------------------- time to success

TARGET = 0.9                                  # success both ways that "time to success" waits for
GOAL = ((2, 0.95), (1, 0.90), (3, 0.90))     # the run goal by the evaluator: (scenario, success both ways at least)
SCENARIO_COLUMNS = (1, 2, 3)
DIRS = ("air_to_water", "water_to_air")


def read_rows(path: str) -> list[dict]:
    """A metrics.csv's rows (the evaluations so far); [] before the file exists."""
    if not os.path.exists(path):
        return []
    with open(path) as f:
        return list(csv.DictReader(f))


def reached(rows: list[dict], target: float) -> dict | None:
    """The first row (one seed) with both paper directions >= target; rows without them are skipped."""
    for r in rows:
        try:
            if float(r["success_air_to_water"]) >= target and float(r["success_water_to_air"]) >= target:
                return r
        except (KeyError, ValueError):
            continue
    return None


def meets_goal(ev: dict | None) -> bool | None:
    """Whether an evaluator's result {(scenario, direction): success} meets every bar of GOAL (None: none)."""
    if ev is None:
        return None
    return all(ev.get((s, d), 0.0) >= bar for s, bar in GOAL for d in DIRS)


def goal_counts(evs: list[dict]) -> tuple[int, int, int]:
    """How many of the evaluator's results `evs` meet the goal's scenario-2 bar, its scenarios 1 and 3 bars
    (both ways each), and the whole goal."""
    bar = dict(GOAL)
    s2 = sum(all(e.get((2, d), 0) >= bar[2] for d in DIRS) for e in evs)
    s13 = sum(all(e.get((s, d), 0) >= bar[s] for s in (1, 3) for d in DIRS) for e in evs)
    return s2, s13, sum(bool(meets_goal(e)) for e in evs)


def pct(x: float | None) -> str:
    """A success fraction as a whole percentage; "–" for none."""
    return "–" if x is None else f"{100 * x:.0f}"


def pair(ev: dict | None, scenario: int) -> str:
    """"A-W / W-A" percentages of `scenario` in an evaluator's result; "–" where it has none."""
    if ev is None or (scenario, DIRS[0]) not in ev:
        return "–"
    return " / ".join(pct(ev[(scenario, d)]) for d in DIRS)

# --------------------------------------------------------------------------------------------------- packs


def unpack(source: str, into: Path, scratch: Path | None = None) -> Path:
    """A GPU job's packs (the $OUT tar of a job, a folder holding pack/ or pack/ itself) unpacked into
    `into`: runs/NAME, eval/NAME, the logs and `times`. A tar is first extracted into `scratch` (default
    into/tar; several jobs unpacked into one `into` need one each). Returns `into`."""
    src = Path(source)
    if src.is_file():
        scratch = into / "tar" if scratch is None else scratch
        with tarfile.open(src) as t:
            t.extractall(scratch, filter="data")
        src = scratch
    pack = src / "pack" if (src / "pack").is_dir() else src
    for f in sorted(pack.glob("runs_*.tgz")):
        with tarfile.open(f) as t:
            t.extractall(into / "runs", filter="data")
    for f in sorted(pack.glob("eval_*.tgz")):
        with tarfile.open(f) as t:
            t.extractall(into, filter="data")
    for name in ("times", "gpu.txt"):
        if (pack / name).is_file():
            (into / name).write_bytes((pack / name).read_bytes())
    return into

# ---------------------------------------------------------------------------------------------------- peers

# Published recipes: name -> trainer -> (brax train() kwargs, network kwargs). Our episode length (500)
# replaces each recipe's own, and the paper's discount 0.99 Brax's Ant recipes'.
#   brax_ant: Brax's Ant recipes (brax README / training notebook). SAC num_envs 128, batch 512, 64
#     gradient updates per step, lr 6e-4, min replay 8192; PPO num_envs 4096, batch 2048, unroll 5, 32
#     minibatches, 4 updates per batch, lr 3e-4, entropy 1e-2, reward scaling 10. Networks: Brax's
#     defaults (SAC 256-256; PPO policy 32x4, value 256x5).
#   playground_dm_control: MuJoCo Playground's tuned dm_control-suite recipes
#     (mujoco_playground/config/dm_control_suite_params.py, the settings every task shares).
#   playground_locomotion: MuJoCo Playground's locomotion PPO recipe (locomotion_params.py, its default:
#     8,192 envs, batch 256, unroll 20, discount 0.97, gradient clipping 1; policy 128x4, value 256x5).
PEER_RECIPES = {
    "brax_ant": {
        "sac": (dict(num_timesteps=20_000_000, num_evals=50, episode_length=500, action_repeat=1, num_envs=128,
                     batch_size=512, grad_updates_per_step=64, learning_rate=6e-4, discounting=0.99,
                     reward_scaling=1.0, normalize_observations=True, min_replay_size=8192,
                     max_replay_size=1_048_576, num_eval_envs=128, deterministic_eval=True),
                {"hidden_layer_sizes": (256, 256)}),
        "ppo": (dict(num_timesteps=200_000_000, num_evals=50, episode_length=500, action_repeat=1, num_envs=4096,
                     batch_size=2048, unroll_length=5, num_minibatches=32, num_updates_per_batch=4,
                     learning_rate=3e-4, entropy_cost=1e-2, discounting=0.99, reward_scaling=10.0,
                     normalize_observations=True, num_eval_envs=128, deterministic_eval=True),
                {"policy_hidden_layer_sizes": (32, 32, 32, 32), "value_hidden_layer_sizes": (256,) * 5}),
    },
    "playground_dm_control": {
        "sac": (dict(num_timesteps=5_000_000, num_evals=10, episode_length=500, action_repeat=1, num_envs=128,
                     batch_size=512, grad_updates_per_step=8, learning_rate=1e-3, discounting=0.99,
                     reward_scaling=1.0, normalize_observations=True, min_replay_size=8192,
                     max_replay_size=4 * 1_048_576, num_eval_envs=128, deterministic_eval=True),
                {"hidden_layer_sizes": (256, 256), "q_network_layer_norm": True}),
        "ppo": (dict(num_timesteps=60_000_000, num_evals=10, episode_length=500, action_repeat=1, num_envs=2048,
                     batch_size=1024, unroll_length=30, num_minibatches=32, num_updates_per_batch=16,
                     learning_rate=1e-3, entropy_cost=1e-2, discounting=0.995, reward_scaling=10.0,
                     normalize_observations=True, num_resets_per_eval=10, num_eval_envs=128,
                     deterministic_eval=True),
                {"policy_hidden_layer_sizes": (32, 32, 32, 32), "value_hidden_layer_sizes": (256,) * 5}),
    },
    "playground_locomotion": {
        "ppo": (dict(num_timesteps=100_000_000, num_evals=10, episode_length=500, action_repeat=1, num_envs=8192,
                     batch_size=256, unroll_length=20, num_minibatches=32, num_updates_per_batch=4,
                     learning_rate=3e-4, entropy_cost=1e-2, discounting=0.97, reward_scaling=1.0,
                     max_grad_norm=1.0, normalize_observations=True, num_resets_per_eval=10,
                     num_eval_envs=128, deterministic_eval=True),
                {"policy_hidden_layer_sizes": (128,) * 4, "value_hidden_layer_sizes": (256,) * 5}),
    },
}
DEFAULT_PEER_RECIPE = "brax_ant"


def peer_recipe(name: str, trainer: str) -> tuple[dict, dict]:
    """(train kwargs, network kwargs) of a published recipe; an error names the valid choices."""
    if name not in PEER_RECIPES:
        raise SystemExit(f"--recipe {name!r}: unknown; valid: {', '.join(PEER_RECIPES)}")
    if trainer not in PEER_RECIPES[name]:
        raise SystemExit(f"--recipe {name!r} has no {trainer} recipe; it has: {', '.join(PEER_RECIPES[name])}")
    cfg, nets = PEER_RECIPES[name][trainer]
    return dict(cfg), dict(nets)
