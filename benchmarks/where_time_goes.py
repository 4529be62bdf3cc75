"""Where the time goes: launch -> first training step, and one training iteration, by wall-clock brackets.

    python benchmarks/where_time_goes.py --config td3_lstm --repeats 3 --out benchmarks/results/h100/where_time_goes

Start-up: each repeat runs two fresh processes of `startup` (the first with an empty compilation cache:
cold; the second with the cache the first filled: warm). A child times, from the moment the parent
launched it (so interpreter start-up counts), every phase the train command goes through, one after
the other: imports, config, devices, the trainer's pure functions (MJCF parse, MJX model, the env's
first forward), the runner state's shapes, then for each program (init, chunk, evaluate) tracing,
lowering and compiling (a cache hit still traces and lowers: the cache key is the lowered program),
then running init, the first evaluation and the first two chunks. The train command compiles the
three programs in threads; here they run serially so each phase has its own figure. The chunk here is
the full build alone: a cold train command on a GPU first trains on a quick build of it
(docrl_jax/train/programs.py, `Tiered`), which this script does not time.

Iteration: one process builds a real runner state (init + one chunk, so the buffer holds data and
learning has started), then times the pieces of one training iteration on it, each repeated `--iters`
times inside one jitted scan (as in the chunk: a separately dispatched call would mostly time its
dispatch), median of 5 calls: the env step of all envs, acting (actor + exploration noise), the
replay insert, sampling one batch, the critic loss and its gradient, the actor loss and its gradient,
one whole update (critic, delayed actor, targets), `updates_per_step` updates with their sampling,
and one whole iteration (a chunk / iterations per chunk).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

T_LAUNCH = float(os.environ.get("WTG_LAUNCH", time.time()))


def _mark(marks: list, name: str, t0: float) -> float:
    t = time.time()
    marks.append({"phase": name, "s": round(t - t0, 3)})
    return t


# ------------------------------------------------------------------ start-up (child process)
def startup(config_name: str, cache: str) -> list[dict]:
    marks: list[dict] = []
    t = _mark(marks, "interpreter start (launch -> first line)", T_LAUNCH)
    import jax
    t = _mark(marks, "import jax", t)
    import docrl_jax.envs.huauv  # noqa: F401  (mujoco, mujoco.mjx, warp)
    t = _mark(marks, "import mujoco, mjx (docrl_jax.envs)", t)
    import docrl_jax.train.run  # noqa: F401  (flax, optax, orbax, rich...)
    from docrl_jax.config import load_config
    from docrl_jax.train import program_store, programs
    from docrl_jax.train.evaluation import eval_keys
    from docrl_jax.train.trainer import make_trainer
    t = _mark(marks, "import the rest of the train command (flax, optax, orbax, rich)", t)
    program_store.enable_compile_cache(cache)
    config = load_config(config_name)
    t = _mark(marks, "load and check the config", t)
    devices = jax.devices()
    t = _mark(marks, f"device initialisation ({devices[0].device_kind})", t)
    trainer = make_trainer(program_store.program_config(config))
    t = _mark(marks, "make_trainer (MJCF parse, MJX model, env's first forward)", t)
    import jax.numpy as jnp
    init, chunk, evaluate, eval_starts = programs.jitted_programs(program_store.program_config(config), (devices[0],), False)
    n = config.train.num_seeds
    keys = jax.ShapeDtypeStruct((n, 2), jnp.uint32)
    total = jax.ShapeDtypeStruct((), jnp.int32)
    state_shape = jax.eval_shape(init, keys, total)
    t = _mark(marks, "runner state shapes (eval_shape of init)", t)
    compiled = {}
    phases = [("init", init, (keys, total)), ("chunk", chunk, (state_shape,)),
              ("evaluate", evaluate, (state_shape.agent.actor_average, keys))]
    if eval_starts is not None:  # train.eval_alongside
        phases.append(("eval_starts", eval_starts, (keys,)))
    for name, fn, args in phases:
        traced = fn.trace(*args)
        t = _mark(marks, f"{name}: trace", t)
        lowered = traced.lower()
        t = _mark(marks, f"{name}: lower", t)
        compiled[name] = lowered.compile()
        t = _mark(marks, f"{name}: compile (or cache load)", t)
    seed_keys = jnp.stack([jax.random.PRNGKey(s) for s in range(n)])
    state = jax.block_until_ready(compiled["init"](seed_keys, jnp.int32(trainer.total_env_steps)))
    t = _mark(marks, "run init (envs reset, empty buffer on the device)", t)
    jax.block_until_ready(compiled["evaluate"](state.agent.actor_average, eval_keys(list(range(n)), 0)))
    t = _mark(marks, "first evaluation (the paper's pairs, 100 episodes each)", t)
    state, m = compiled["chunk"](state)
    jax.block_until_ready(m)
    t = _mark(marks, "first chunk (random actions until start_steps, then learning)", t)
    state, m = compiled["chunk"](state)
    jax.block_until_ready(m)
    _mark(marks, "second chunk (learning)", t)
    return marks


# ------------------------------------------------------------------ one iteration (in process)
def _per_rep(fn, carry, reps: int, calls: int) -> float:
    """Seconds per repetition of `fn(carry) -> carry` run `reps` times in ONE jitted scan (as inside
    the chunk: no per-call dispatch), median over `calls` calls after a warm-up call."""
    import jax
    prog = jax.jit(lambda c: jax.lax.scan(lambda c, _: (fn(c), None), c, None, length=reps)[0])
    jax.block_until_ready(prog(carry))
    times = []
    for _ in range(calls):
        t0 = time.perf_counter()
        jax.block_until_ready(prog(carry))
        times.append(time.perf_counter() - t0)
    return statistics.median(times) / reps


def iteration(config_name: str, iters: int) -> tuple[list[dict], dict]:
    """Each piece repeated `iters` times in one scan, every repetition feeding the next (so XLA
    cannot hoist it out of the loop): per-repetition times as the chunk sees them."""
    import jax
    import jax.numpy as jnp
    from docrl_jax.algorithms import td3
    from docrl_jax.algorithms.common import split_batch
    from docrl_jax.networks import make_critic
    from docrl_jax.config import load_config
    from docrl_jax.replay import make_sequence_buffer
    from docrl_jax.train.trainer import buffer_step, make_trainer

    config = load_config(config_name)
    tr = make_trainer(config)
    e, r, tc, a_cfg = config.env, config.replay, config.train, config.agent
    agent, env = tr.agent, tr.env
    buffer = make_sequence_buffer(e.num_envs, r.buffer_size // e.num_envs, r.batch_size, r.seq_len)
    chunk = jax.jit(tr.chunk, donate_argnums=0)
    rs = jax.block_until_ready(jax.jit(tr.init)(jax.random.PRNGKey(0)))
    rs, _ = chunk(rs)   # buffer filled past start_steps: learning has begun
    rs = jax.block_until_ready(rs)
    n = e.num_envs
    key = jax.random.PRNGKey(1)
    progress = jnp.float32(0.5)
    calls = 5
    rows = []

    def add(name, seconds, per="iteration", note=""):
        rows.append({"piece": name, "ms": round(seconds * 1e3, 3), "per": per, "note": note})

    nudge = lambda tree, g: jax.tree.map(lambda p, d: p + 1e-9 * d, tree, g)  # noqa: E731
    actions = jnp.zeros((n, 3))
    lanes = rs.env.obs.shape[0]   # the training envs, then the evaluation's lanes (train.eval_alongside)
    obs = rs.env.obs[:n]
    stepped = f"{lanes:,} envs" + (f": {n:,} training + {lanes - n} evaluation lanes" if lanes > n else "")
    add(f"env step ({stepped})",
        _per_rep(lambda s: jax.vmap(env.step)(s, jnp.zeros((lanes, 3))), rs.env, iters, calls))
    add("act: actor + exploration noise",
        _per_rep(lambda c: agent.explore(rs.agent, c[0], c[1], obs + 1e-9 * c[2][:, :1], rs.start, key,
                                         progress), (rs.carry, rs.noise, actions), iters, calls))
    example = buffer_step(obs, actions, rs.ep_return, obs, rs.start, rs.start, rs.start, rs.carry)
    add("replay insert", _per_rep(lambda b: buffer.add(b, example), rs.buffer, iters, calls))
    buf = rs.buffer
    add(f"sample one batch ({r.batch_size:,} x {r.seq_len})",
        _per_rep(lambda k: k + _touch(buffer.sample(buf, k)), key, iters, calls),
        "update")
    batch = buffer.sample(buf, key)
    if a_cfg.algo in ("td3", "ddpg"):
        critic = make_critic(config.agent)
        seq = split_batch(batch, r.burn_in)
        noise = jax.random.normal(key, seq.action.shape)
        critic_grad = jax.grad(lambda p: td3.critic_loss(p, critic, agent.actor, rs.agent, seq, noise, a_cfg,
                                                         a_cfg.recurrent)[0])
        add("critic loss + gradient (target actor over the sequence, twin critics)",
            _per_rep(lambda p: nudge(p, critic_grad(p)), rs.agent.critic, iters, calls), "update")
        actor_grad = jax.grad(lambda p: td3.actor_loss(p, agent.actor, critic, rs.agent.critic, seq, a_cfg.recurrent))
        add("actor loss + gradient (actor over the sequence, critic 1)",
            _per_rep(lambda p: nudge(p, actor_grad(p)), rs.agent.actor, iters, calls), "update (delayed)")
    # The delayed actor branch runs when updates % policy_freq == 0: policy_freq(0) schedules it.
    update = lambda a: agent.update(a, batch, key, progress)[0]  # noqa: E731
    add("one update on a fixed batch (critic, delayed actor, targets)", _per_rep(update, rs.agent, iters, calls),
        "update")

    def updates(a):
        def one(a, k):
            k_sample, k_loss = jax.random.split(k)
            return agent.update(a, buffer.sample(buf, k_sample), k_loss, progress)[0], None
        return jax.lax.scan(one, a, jax.random.split(key, tc.updates_per_step))[0]
    add(f"{tc.updates_per_step} updates with sampling", _per_rep(updates, rs.agent, max(1, iters // 4), calls))
    per_chunk = []
    for _ in range(calls + 1):
        t0 = time.perf_counter()
        rs, m = chunk(rs)
        jax.block_until_ready(m)
        per_chunk.append(time.perf_counter() - t0)
    it = statistics.median(per_chunk[1:]) / tr.iters_per_chunk
    add(f"whole iteration (a chunk of {tr.iters_per_chunk}, per iteration)", it,
        note=f"{n / it:,.0f} env steps/s")
    facts = {"num_envs": n, "batch_size": r.batch_size, "seq_len": r.seq_len, "burn_in": r.burn_in,
             "updates_per_step": tc.updates_per_step, "iters_per_chunk": tr.iters_per_chunk, "reps": iters}
    return rows, facts


def _touch(tree):
    """0 (uint32) computed from every element of `tree`, so no part of its computation is dead code."""
    import jax
    import jax.numpy as jnp
    total = sum(jnp.sum(x.astype(jnp.float32)) for x in jax.tree.leaves(tree))
    return (total > 3e38).astype(jnp.uint32)


# ------------------------------------------------------------------ parent
def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", default="td3_lstm")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--iters", type=int, default=50)
    p.add_argument("--out", required=True)
    p.add_argument("--child", choices=["startup"], help=argparse.SUPPRESS)
    p.add_argument("--cache", help=argparse.SUPPRESS)
    p.add_argument("--skip-startup", action="store_true")
    p.add_argument("--skip-iteration", action="store_true")
    args = p.parse_args()
    if args.child == "startup":
        print(json.dumps(startup(args.config, args.cache)))
        return
    from common import run_meta
    meta = run_meta()
    runs = {"cold": [], "warm": []}
    base = []
    if not args.skip_startup:
        for rep in range(args.repeats):
            t0 = time.time()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            base.append(time.time() - t0)
            with tempfile.TemporaryDirectory() as cache:
                for kind in ("cold", "warm"):
                    env = {**os.environ, "WTG_LAUNCH": repr(time.time())}
                    out = subprocess.run([sys.executable, __file__, "--child", "startup", "--config", args.config,
                                          "--cache", cache, "--out", args.out], env=env, capture_output=True,
                                         text=True, check=True)
                    runs[kind].append(json.loads(out.stdout.strip().splitlines()[-1]))
                    print(kind, rep, sum(m["s"] for m in runs[kind][-1]), flush=True)
    rows, facts = ([], None) if args.skip_iteration else iteration(args.config, args.iters)
    result = {**meta, "config": args.config, "python_bare_start_s": base, "startup": runs, "iteration": rows,
              "iteration_facts": facts}
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "where_time_goes.json"), "w") as f:
        json.dump(result, f, indent=1)
    with open(os.path.join(args.out, "where_time_goes.md"), "w") as f:
        f.write(markdown(result))
    print(markdown(result))


def markdown(res: dict) -> str:
    lines = [f"# Where the time goes: {res['config']} ({res['gpu']}, {res['date']})", "",
             f"Command: `{res['command']}`  ", f"Versions: {res['versions']}", ""]
    if res["startup"]["cold"]:
        phases = [m["phase"] for m in res["startup"]["cold"][0]]
        med = {k: [statistics.median(r[i]["s"] for r in res["startup"][k]) for i in range(len(phases))]
               for k in ("cold", "warm")}
        lines += [f"## Launch to the first training step (median of {len(res['startup']['cold'])} launches, s)", "",
                  "| phase | cold cache | warm cache |", "|---|---|---|"]
        lines += [f"| {ph} | {c:.2f} | {w:.2f} |" for ph, c, w in zip(phases, med["cold"], med["warm"])]
        lines += [f"| **total** | **{sum(med['cold']):.2f}** | **{sum(med['warm']):.2f}** |", "",
                  f"A bare `python -c pass` takes {statistics.median(res['python_bare_start_s']):.2f} s.", ""]
    f = res["iteration_facts"]
    if f is None:
        return "\n".join(lines) + "\n"
    lines += [f"## One training iteration ({f['num_envs']:,} envs, {f['updates_per_step']} updates of "
              f"{f['batch_size']:,} x {f['seq_len']} (burn-in {f['burn_in']}); median ms)", "",
              "| piece | ms | per | note |", "|---|---|---|---|"]
    lines += [f"| {r['piece']} | {r['ms']:.3f} | {r['per']} | {r['note']} |" for r in res["iteration"]]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
