"""The trainer program: env steps, action selection, replay insertion and gradient updates in one
`jax.lax.scan`, compiled once (PureJaxRL style).

One *iteration* = every env takes one step (num_envs transitions enter the replay buffer), then
`train.updates_per_step` gradient updates run, each on `replay.batch_size` sequences of
`replay.seq_len` steps. Hence
    update-to-data ratio (UTD)  = updates_per_step / num_envs          gradient updates per transition
    replay ratio                = updates_per_step * batch_size * (seq_len - burn_in) / num_envs
                                                                     trained steps per collected step
The original trained 1 env with 1 update of 256 per step (UTD 1, replay ratio 256). Raising
num_envs at fixed updates_per_step collects data faster but lowers UTD; to keep UTD fixed, scale
updates_per_step with num_envs (updates are sequential, envs are parallel, so wall-clock grows).
Updates begin once `train.start_steps` env steps (all envs together) are collected, during which
actions are uniform in [-1, 1]^3 (paper's start_steps).

A *chunk* is `log_every` env steps of iterations (rounded up to whole iterations). The training
loop (docrl_jax.train.loop) calls the compiled chunk repeatedly, donating the runner state, and
between chunks logs, evaluates (docrl_jax.train.evaluation) and checkpoints. With
`train.eval_alongside` the evaluation's episodes are extra env lanes after the num_envs training
envs, stepped in the same vectorised step by a frozen copy of the policy: an evaluation the host
asks for (`RunnerState.evals.begin`, with the episodes' first states from `eval_starts`, a program of
its own) starts with the next chunk, and each chunk reports the lanes' tally. `make_train`'s
`train(key)` runs all chunks in one program without evaluation.
"""

from __future__ import annotations

import functools
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

import docrl_jax.envs as envs
from docrl_jax.algorithms import Agent, AgentState, make_agent
from docrl_jax.config import Config, env_kwargs
from docrl_jax.envs.curriculum import make_curriculum
from docrl_jax.networks import expand_flag
from docrl_jax.replay import BufferState, make_sequence_buffer
from docrl_jax.train.evaluation import make_evaluation
from docrl_jax.train.chunks import schedule


@struct.dataclass
class RunnerState:
    agent: AgentState
    buffer: BufferState
    env: Any                 # EnvState of num_envs envs (then the evaluation lanes, with train.eval_alongside)
    carry: Any               # actor carry after the last step, [num_envs, ...]
    noise: jax.Array         # exploration noise state, [num_envs, 3]
    start: jax.Array         # [num_envs] bool: env.obs is the first obs of an episode
    ep_return: jax.Array     # [num_envs] running return of the current episode
    ep_arrivals: jax.Array   # [num_envs] goals reached in the current episode
    env_steps: jax.Array     # () int32 env steps done, all envs together
    total_steps: jax.Array   # () int32 env steps of the whole run (schedules use env_steps / total_steps);
                             # state rather than a constant, so runs of any length share one program
    key: jax.Array
    evals: Any = None        # evaluation.Lanes with train.eval_alongside: the evaluation's episodes are then
                             # the last lanes of `env`, after the num_envs training envs
    levels: Any = None       # curriculum.LevelPool with levels.sampler 'uniform' or 'learnability'
    level: Any = None        # [num_envs] int32: the pool level each env flies (with a pool)


class Trainer(NamedTuple):
    config: Config
    agent: Agent
    env: Any
    iters_per_chunk: int
    num_chunks: int
    steps_per_chunk: int
    total_env_steps: int     # total_env_steps rounded up to whole chunks
    init: Callable           # key -> RunnerState (one seed)
    init_total: Callable     # (key, total_steps, hp=None) -> RunnerState (one seed)
    chunk: Callable          # (RunnerState, hp=None) -> (RunnerState, chunk metrics) (one seed)
    train: Callable          # key -> (RunnerState, metrics stacked over chunks) (one seed)
    evaluate: Callable       # (actor_params, key) -> eval metrics (one seed)
    eval_starts: Callable | None  # key -> the evaluation lanes' first states (train.eval_alongside), else None
    init_carry: Callable     # batch_shape -> zero actor carry
    memory: bool


def make_train(config: Config) -> Callable:
    """Pure `train(key) -> (runner_state, metrics)` for one seed; jit and vmap it freely."""
    return make_trainer(config).train


@functools.lru_cache(maxsize=8)
def make_trainer(config: Config) -> Trainer:
    """Builds the pure functions of a run. Memoised on the (hashable) config: building the env costs
    a second, and returning the same functions lets the compiled programs' cache hit."""
    e, r, t = config.env, config.replay, config.train
    env = envs.make(e.scenario, auto_reset=True, **env_kwargs(config))
    agent = make_agent(config)
    memory = config.agent.recurrent
    buffer = make_sequence_buffer(e.num_envs, r.buffer_size // e.num_envs, r.batch_size, r.seq_len)
    iters_per_chunk, steps_per_chunk, num_chunks, total = schedule(config)
    n = e.num_envs

    def init_carry(batch_shape=()):
        return agent.actor.init_carry(batch_shape)

    evaluation = make_evaluation(config, agent.act, init_carry, memory, env)
    pool = None
    if config.levels.sampler != "env":   # a level pool (docrl_jax/envs/curriculum.py)
        lv = config.levels
        pool = make_curriculum(env, lv.sampler, lv.capacity, lv.refresh, lv.temperature, lv.uniform_mix,
                               keep_fields=lv.route_reward > 0)
    lanes = evaluation.alongside   # None, or the evaluation's env lanes after the n training envs
    train_rows = (lambda x: x[:n]) if lanes else (lambda x: x)  # noqa: E731

    def init(key) -> RunnerState:
        return init_total(key, total)

    # `hp` (algorithms.HParams): None = the config's values as constants (a plain run); a sweep
    # (docrl_jax.train.sweep) passes them as traced inputs, one set per seed row.
    def init_total(key, total_steps, hp=None) -> RunnerState:
        k_agent, k_env, k_run = jax.random.split(key, 3)
        levels = level = None
        if pool:
            k_pool, k_level = jax.random.split(jax.random.fold_in(k_env, 1))
            levels = pool.init(k_pool)
            level = pool.sample(levels, k_level, n)
            env_state = jax.vmap(lambda k, lv: env.reset(k, layout=lv))(jax.random.split(k_env, n),
                                                                         pool.take(levels, level))
        else:
            env_state = jax.vmap(env.reset)(jax.random.split(k_env, n))
        example = buffer_step(env_state.obs[0], jnp.zeros(3), jnp.zeros(()), env_state.obs[0], jnp.zeros((), bool),
                               jnp.zeros((), bool), jnp.zeros((), bool), init_carry())
        agent_state = agent.init(k_agent, hp)
        evals = None
        if lanes:  # idle lanes until the host asks for an evaluation: copies of the training envs' first
            # states (no second reset to compile, the training envs' draws unchanged; an idle lane is never read)
            idle = jax.tree.map(lambda x: x[jnp.arange(lanes.size) % n], env_state)
            env_state = jax.tree.map(lambda *xs: jnp.concatenate(xs), env_state, idle)
            evals = lanes.init(agent_state.actor_average, idle)
        return RunnerState(agent=agent_state, buffer=buffer.init(example), env=env_state,
                           carry=init_carry((n,)), noise=agent.init_noise(n), start=jnp.ones(n, bool),
                           ep_return=jnp.zeros(n), ep_arrivals=jnp.zeros(n, jnp.int32),
                           env_steps=jnp.zeros((), jnp.int32),
                           total_steps=jnp.asarray(total_steps, jnp.int32), key=k_run, evals=evals,
                           levels=levels, level=level)

    def chunk(rs: RunnerState, hp=None):
        def iteration(rs: RunnerState, _):
            key, k_act, k_rand, k_upd = jax.random.split(rs.key, 4)
            progress = rs.env_steps.astype(jnp.float32) / rs.total_steps.astype(jnp.float32)

            # 1. Act: reset the carry where an episode starts (all steps when memoryless), explore.
            zero = init_carry((n,))
            if memory:
                carry_in = jax.tree.map(lambda z, c: jnp.where(expand_flag(rs.start, c), z, c), zero, rs.carry)
            else:
                carry_in = zero
            obs = train_rows(rs.env.obs)
            carry, noise, action = agent.explore(rs.agent, carry_in, rs.noise, obs, rs.start, k_act, progress, hp)
            random_phase = rs.env_steps < t.start_steps
            uniform = jax.random.uniform(k_rand, action.shape, minval=-1.0, maxval=1.0)
            action = jnp.where(random_phase, uniform, action)
            evals = rs.evals
            if lanes:  # the evaluation's episodes, by their own policy, in the same vectorised step
                evals, lane_action = lanes.act(evals, rs.env.obs[n:])
                action_all = jnp.concatenate([action, lane_action])
            else:
                action_all = action

            # 2. Step all envs (auto-reset; with a pool, an ended episode restarts in a pool level) and
            # store the transition with its true next obs.
            if pool:
                k_level = jax.random.fold_in(k_rand, 1)
                next_level = pool.sample(rs.levels, k_level, n)
                env_state = jax.vmap(env.step)(rs.env, action_all, pool.take(rs.levels, next_level))
            else:
                env_state = jax.vmap(env.step)(rs.env, action_all)
            if lanes:
                evals = lanes.count(evals, jax.tree.map(lambda x: x[n:], env_state))
            reward, done, info = jax.tree.map(train_rows, (env_state.reward, env_state.done, env_state.info))
            if pool and config.levels.route_reward:
                reward = reward + _route_progress(pool, rs, info["position"], config.levels.route_reward, n)
            step = buffer_step(obs, action, reward, info["final_obs"], info["terminated"],
                                info["truncated"], rs.start, carry_in)
            buf = buffer.add(rs.buffer, step)

            # 3. Episode statistics of the training envs.
            ep_return = rs.ep_return + reward
            arrivals = rs.ep_arrivals + info["arrived"].astype(jnp.int32)
            episodes = {"episodes": jnp.sum(done), "return_sum": jnp.sum(jnp.where(done, ep_return, 0.0)),
                        "success_sum": jnp.sum(done & (arrivals > 0)),
                        "arrivals": jnp.sum(info["arrived"]), "collisions": jnp.sum(info["terminated"])}
            env_steps = rs.env_steps + n
            levels, level = rs.levels, rs.level
            if pool:
                levels = pool.record(levels, level, done, arrivals > 0)
                level = jnp.where(done, next_level, level)

            # 4. Gradient updates once start_steps are collected and every env holds a sequence. The
            # updates' batches are drawn together, one gather per stored field instead of one per update
            # (the same sequences as drawing each in its update: vmap draws each key's own bits).
            def updates(agent_state, key):
                keys = jax.vmap(jax.random.split)(jax.random.split(key, t.updates_per_step))  # each: (sample, loss)
                batches = jax.vmap(buffer.sample, (None, 0))(buf, keys[:, 0])
                agent_state, m = jax.lax.scan(lambda a, x: agent.update(a, x[0], x[1], progress, hp), agent_state,
                                              (batches, keys[:, 1]))
                return agent_state, _update_summary(m)

            learn = (env_steps > t.start_steps) & buffer.can_sample(buf) & (t.updates_per_step > 0)
            if t.updates_per_step > 0:
                # Jitted, the updates are traced once: eval_shape fills jit's trace cache and the cond's
                # branch reuses it (a second trace took about a fifth of lowering the chunk, in a cold start).
                updates = jax.jit(updates)
                empty = jax.tree.map(lambda s: jnp.zeros(s.shape, s.dtype),
                                     jax.eval_shape(updates, rs.agent, k_upd)[1])
                agent_state, upd = jax.lax.cond(learn, updates, lambda a, k: (a, empty), rs.agent, k_upd)
            else:
                agent_state, upd = rs.agent, {}

            rs = RunnerState(agent=agent_state, buffer=buf, env=env_state, carry=carry, noise=noise, start=done,
                             ep_return=jnp.where(done, 0.0, ep_return),
                             ep_arrivals=jnp.where(done, 0, arrivals), env_steps=env_steps,
                             total_steps=rs.total_steps, key=key, evals=evals, levels=levels, level=level)
            return rs, {**episodes, **upd, "learn": learn}

        if lanes:  # an evaluation the host asked for begins with this chunk, on the policy as it is now
            def begin(rs):
                evals, env_state = lanes.begin(rs.evals, rs.env, rs.agent.actor_average)
                return rs.replace(evals=evals, env=env_state)
            rs = jax.lax.cond(rs.evals.begin, begin, lambda rs: rs, rs)
        pool_metrics = {}
        if pool:   # fresh flyable levels into the pool, the sampling weights recomputed
            k_refresh, k_run = jax.random.split(rs.key)
            levels, pool_metrics = pool.refresh(rs.levels, k_refresh)
            rs = rs.replace(levels=levels, key=k_run)
        rs, m = jax.lax.scan(iteration, rs, None, length=iters_per_chunk)
        out = {**_chunk_summary(m), **pool_metrics}
        if lanes:  # the lanes' tally after this chunk: final once none is running
            out["evaluation"] = lanes.results(rs.evals)
        return rs, out

    def train(key):
        return jax.lax.scan(lambda rs, _: chunk(rs), init(key), None, length=num_chunks)

    return Trainer(config=config, agent=agent, env=env, iters_per_chunk=iters_per_chunk, num_chunks=num_chunks,
                   steps_per_chunk=steps_per_chunk, total_env_steps=total, init=init, init_total=init_total, chunk=chunk, train=train,
                   evaluate=evaluation.evaluate, eval_starts=lanes.starts if lanes else None, init_carry=init_carry,
                   memory=memory)


def _route_progress(pool, rs: RunnerState, position, scale: float, n: int):
    """levels.route_reward: scale x the metres this step took off the route to the goal's region of the
    level (its distance field, which knows the way round walls where the straight line does not); 0 where
    the step began or ended off the field's free cells."""
    start = rs.env.sim.data.qpos[:n, :3]        # this step's start (a new episode's first position too)
    water = rs.env.sim.goal[:n, 2] < 0.0        # the goal this step flew to
    before = pool.to_region(rs.levels, rs.level, water, start)
    after = pool.to_region(rs.levels, rs.level, water, position)
    return jnp.where(jnp.isfinite(before) & jnp.isfinite(after), scale * (before - after), 0.0)


def buffer_step(obs, action, reward, next_obs, terminated, truncated, start, carry) -> dict:
    """One step of experience as the replay buffer stores it (its pytree structure)."""
    return {"obs": obs, "action": action, "reward": reward, "next_obs": next_obs, "terminated": terminated,
            "truncated": truncated, "start": start, "carry": carry}


def _update_summary(m: dict) -> dict:
    """Means over the updates of one iteration; the actor loss only over steps that updated the actor."""
    out = {k: jnp.mean(v.astype(jnp.float32)) for k, v in m.items() if k not in ("actor_loss", "alpha_loss")}
    w = m["actor_updated"]
    for k in ("actor_loss", "alpha_loss"):
        if k in m:
            out[k] = jnp.sum(m[k] * w) / jnp.maximum(jnp.sum(w), 1.0)
    out["actor_updates"] = jnp.sum(w)
    out["updates"] = jnp.asarray(w.shape[0], jnp.float32)
    return out


def _chunk_summary(m: dict) -> dict:
    """Chunk metrics: episode statistics summed, losses averaged over iterations that learned, and
    the first iteration whose losses were not finite (-1 if none)."""
    learn = m.pop("learn").astype(jnp.float32)
    out = {k: jnp.sum(m[k]) for k in ("episodes", "return_sum", "success_sum", "arrivals", "collisions")}
    nlearn = jnp.maximum(jnp.sum(learn), 1.0)
    bad = jnp.zeros_like(learn, bool)
    for k, v in m.items():
        if k in out:
            continue
        if k in ("updates", "actor_updates"):
            out[k] = jnp.sum(v)
            continue
        bad = bad | ~jnp.isfinite(v)
        out[k] = jnp.sum(jnp.where(learn > 0, jnp.nan_to_num(v), 0.0)) / nlearn
    out["learn_iters"] = jnp.sum(learn)
    out["nonfinite_iter"] = jnp.where(jnp.any(bad), jnp.argmax(bad), -1)
    return out
