"""Deterministic evaluation of the run's policy (learning curves in metrics.csv).

`make_evaluation(config, act, init_carry, memory, train_env)` returns the evaluation's pure
functions. Each evaluation runs `eval_episodes` episodes in parallel with the deterministic policy
(TD3/DDPG: actor output; SAC: tanh(mean)), each until the goal is reached (success), a collision or
bound ends it, or the step limit (env.max_episode_steps) truncates it. Starts and goals follow the
training distribution; with `train.eval_paper_pairs` the paper's air-to-water and water-to-air pairs
(`envs.eval_pair`, in the run's scenario, or `train.eval_pair_scenario` for a procedural run, with the
nominal plant) are run too, from the evaluator's trial starts (`train.eval_pair_starts`, see
`pair_starts`), and for each pair the fractions of episodes that ended in a collision or out of
bounds are reported too (the rest of the failures are time-outs): a direction that stalls below 90 %
says why in metrics.csv. The full protocol of the paper (100 trials, times in air/water, 0.01 m range
noise) is the evaluator's job, not this module's; these episodes use the training env's settings
(without `env.collision_margin` and `env.hull_margin`, which are for training only).

The same episodes run in one of two ways:

* `evaluate(actor_params, key)`: a program of its own, between chunks, that steps the episodes until
  the last has ended (training waits for it);
* alongside training (`train.eval_alongside`, `Alongside`): the episodes are extra lanes of the
  training envs, stepped in the chunk's own vectorised env step by a frozen copy of the policy, and
  counted by the same `Tally`. An episode under the training env's auto-reset is exactly the env's
  episode until it ends (docrl_jax.envs.wrappers), a lane stops counting at its first arrival
  (the training env goes on to a new goal where the evaluation's own env stops), and a lane's episode
  runs without the training-only margins (its state's `training_margins` is cleared), so both ways give
  the same results from the same key.
"""

from __future__ import annotations

from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

import docrl_jax.envs as envs
from docrl_jax.config import Config, evaluation_env_kwargs, nominal_env_kwargs, pair_scenario, pairs_own_env
from docrl_jax.evaluate.protocol import DIRECTIONS, NOMINAL_YAW, trial_starts
from docrl_jax.sharding import on_host


_EVAL_SALT = 0x5EA1


def eval_keys(seeds: list[int], env_steps: int) -> np.ndarray:
    """Keys (one per seed) of the evaluation at `env_steps`: a function of seed and step only, so a
    resumed run evaluates on exactly the episodes an uninterrupted one would. Computed on the host
    (`sharding.on_host`)."""
    with on_host():
        return np.stack([np.asarray(jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(s), _EVAL_SALT),
                                                       env_steps)) for s in seeds])


def pair_starts(how: str, key: jax.Array, start, direction: str, n: int) -> tuple[jax.Array, jax.Array]:
    """Start positions (n, 3) and yaws (n,) of the paper-pair episodes of one direction.

    'paper': the evaluator's trials (`evaluate.protocol.trial_starts`: nominal yaw of the direction +-0.1 rad,
    position +-0.1 m), so the training-time score estimates the paper protocol's. 'random_yaw': the
    exact start, facing a uniformly random yaw (harder: the vehicle must first turn towards its goal)."""
    if how == "paper":
        return trial_starts(key, start, n, NOMINAL_YAW[direction])
    positions = jnp.broadcast_to(jnp.asarray(start, jnp.float32), (n, 3))
    return positions, jax.random.uniform(key, (n,), minval=-jnp.pi, maxval=jnp.pi)


class Tally(NamedTuple):
    """Per-episode outcome of an evaluation so far, (m,) each."""
    alive: jax.Array        # still running
    success: jax.Array      # reached the goal
    collision: jax.Array
    out_of_bounds: jax.Array  # out of bounds without a collision, as the evaluator counts it
    ret: jax.Array          # return so far

    @staticmethod
    def start(m: int, alive: bool = True) -> "Tally":
        no = jnp.zeros(m, bool)
        return Tally(jnp.full(m, alive), no, no, no, jnp.zeros(m))

    def count(self, st) -> "Tally":
        """After one env step of the episodes (`st`, batched): an episode ends at its first done or
        arrival (in the evaluation's own env an arrival is a done; the training env goes on)."""
        info, alive = st.info, self.alive
        return Tally(alive=alive & ~(st.done | info["arrived"]),
                     success=self.success | (alive & info["arrived"]),
                     collision=self.collision | (alive & info["collision"]),
                     out_of_bounds=self.out_of_bounds | (alive & info["out_of_bounds"] & ~info["collision"]),
                     ret=self.ret + jnp.where(alive, st.reward, 0.0))


@struct.dataclass
class Lanes:
    """The evaluation alongside training: its policy, carry and tally, and the host's request."""
    params: Any             # the policy under evaluation: the actor's average when the evaluation began
    carry: Any              # its carry over the lanes
    tally: Tally
    begin: jax.Array        # () bool, set by the host: the next chunk begins an evaluation from `fresh`
    fresh: Any              # EnvState of the lanes: the first states of the next evaluation's episodes
                            # (`Alongside.starts` of its key, a program of its own: the chunk only copies them)


class Alongside(NamedTuple):
    """Pure functions of the evaluation lanes: the last `size` envs of the training batch."""
    size: int
    starts: Callable        # key -> EnvState of `size` lanes: an evaluation's episodes, as `evaluate` starts them
    init: Callable          # (actor params, EnvState of `size` lanes) -> Lanes (idle)
    begin: Callable         # (Lanes, env state (n + size), actor params) -> (Lanes, env state): fresh episodes
    act: Callable           # (Lanes, obs (size, 26)) -> (Lanes, actions (size, 3))
    count: Callable         # (Lanes, env state of the lanes after the step) -> Lanes
    results: Callable       # Lanes -> the evaluation's metrics as `evaluate` returns them, and "running"


class Evaluation(NamedTuple):
    evaluate: Callable                # (actor_params, key) -> eval metrics (a program of its own)
    alongside: Alongside | None       # with train.eval_alongside


def make_evaluation(config: Config, act, init_carry, memory: bool, train_env) -> Evaluation:
    env = envs.make(config.env.scenario, auto_reset=False,
                    **{**evaluation_env_kwargs(config), "terminate_on_arrival": True})
    scenario = pair_scenario(config)
    # The pairs get an env of their own only when they run and differ from the training env.
    pair_env = (envs.make(scenario, auto_reset=False, **{**nominal_env_kwargs(config), "terminate_on_arrival": True})
                if pairs_own_env(config) else env)
    n, horizon = config.train.eval_episodes, env.params.max_episode_steps
    names = ["success_rate"] + ([f"success_{d}" for d in DIRECTIONS] if config.train.eval_paper_pairs else [])

    def starts(key, env, pair_env) -> list:
        """The first states of the evaluation's groups of n episodes (`names`), from `key`."""
        k_rand, k_pairs = jax.random.split(key)
        groups = [jax.vmap(env.reset)(jax.random.split(k_rand, n))]
        if config.train.eval_paper_pairs:
            for direction, k in zip(DIRECTIONS, jax.random.split(k_pairs)):
                start, goal = envs.eval_pair(scenario, direction)
                k_start, k_reset = jax.random.split(k)
                positions, yaws = pair_starts(config.train.eval_pair_starts, k_start, start, direction, n)
                groups.append(jax.vmap(lambda kk, p, y: pair_env.reset_to(kk, p, y, jnp.array(goal)))(
                    jax.random.split(k_reset, n), positions, yaws))
        return groups

    def policy(actor_params, carry, obs):
        """One deterministic action per episode; a memoryless actor starts from a zero carry each step."""
        return act(actor_params, carry if memory else init_carry((obs.shape[0],)), obs)

    def summary(t: Tally) -> dict:
        f32 = lambda x: x.astype(jnp.float32)  # noqa: E731
        part = lambda x, i: jnp.mean(f32(x[i * n:(i + 1) * n]))  # noqa: E731
        out = {name: part(t.success, i) for i, name in enumerate(names)}
        for i, name in enumerate(names[1:], start=1):  # the paper pairs' failures
            direction = name.removeprefix("success_")
            out[f"collision_{direction}"] = part(t.collision, i)
            out[f"out_of_bounds_{direction}"] = part(t.out_of_bounds, i)
        out["episode_return"] = jnp.mean(t.ret[:n])
        return out

    # ------------------------------------------------------------------ a program of its own
    def run(env, actor_params, states, m) -> Tally:
        """Runs m episodes in parallel until all have ended (at most the step limit). Stopping when
        the last episode ends, instead of always running the full step limit, makes an evaluation of
        a trained policy several times cheaper."""
        def body(c):
            i, st, carry, tally = c
            carry, action = policy(actor_params, carry, st.obs)
            st = jax.vmap(env.step)(st, action)
            return i + 1, st, carry, tally.count(st)

        init = (jnp.zeros((), jnp.int32), states, init_carry((m,)), Tally.start(m))
        return jax.lax.while_loop(lambda c: (c[0] < horizon) & jnp.any(c[3].alive), body, init)[3]

    def evaluate(actor_params, key):
        groups = starts(key, env, pair_env)
        # One batch per env: the env step is compiled once for each (once when the pairs share the env).
        batches = [groups] if pair_env is env else [groups[:1], groups[1:]]
        tallies = []
        for run_env, batch in zip((env, pair_env), batches):
            states = jax.tree.map(lambda *xs: jnp.concatenate(xs), *batch)
            tallies.append(run(run_env, actor_params, states, n * len(batch)))
        return summary(jax.tree.map(lambda *xs: jnp.concatenate(xs), *tallies))

    # ------------------------------------------------------------------ alongside training
    alongside = None
    if config.train.eval_alongside:
        size = n * len(names)
        lanes = slice(-size, None)

        def lane_starts(key):
            states = jax.tree.map(lambda *xs: jnp.concatenate(xs), *starts(key, train_env, train_env))
            # The training env's own episodes end at its training-only margins; an evaluation's do not.
            return states.replace(sim=states.sim.replace(training_margins=jnp.zeros(size, bool)))

        def init(actor_params, fresh) -> Lanes:
            return Lanes(params=actor_params, carry=init_carry((size,)), tally=Tally.start(size, alive=False),
                         begin=jnp.zeros((), bool), fresh=fresh)

        def begin(lanes_state: Lanes, env_state, actor_params):
            env_state = jax.tree.map(lambda full, new: full.at[lanes].set(new), env_state, lanes_state.fresh)
            return lanes_state.replace(params=actor_params, carry=init_carry((size,)), tally=Tally.start(size),
                                       begin=jnp.zeros((), bool)), env_state

        def act_lanes(lanes_state: Lanes, obs):
            carry, action = policy(lanes_state.params, lanes_state.carry, obs)
            return lanes_state.replace(carry=carry), action

        def count(lanes_state: Lanes, stepped) -> Lanes:
            return lanes_state.replace(tally=lanes_state.tally.count(stepped))

        def results(lanes_state: Lanes) -> dict:
            return {**summary(lanes_state.tally), "running": jnp.sum(lanes_state.tally.alive)}

        alongside = Alongside(size=size, starts=lane_starts, init=init, begin=begin, act=act_lanes, count=count,
                              results=results)
    return Evaluation(evaluate=evaluate, alongside=alongside)
