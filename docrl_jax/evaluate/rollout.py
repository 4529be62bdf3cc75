"""The evaluator's rollout: N trials of one policy from one (scenario, direction) pair as ONE
`jit(vmap(lax.scan))`, and the per-trial metrics computed from its records.

This rollout is separate from the trainer's in-training evaluation because it records every step
(position, medium, action, reward) over the full `max_steps` horizon, which t_air/t_water, the path
length and the trajectory figures need. The trainer's is a `while_loop` that stops once every episode
has ended and returns outcomes only, which is all a training-time score needs and much cheaper.

Trials start either from poses (`run_trials`: the paper's pairs, `env.reset_to` inside the
rollout) or from given initial states (`run_from_states`: e.g. `env.reset(key, layout=...)` of a
held-out procedural layout, made by `reset_states`); both run the one scan of `make_rollout`.

A trial ends at arrival (3-D distance < the env's `arrival_distance`), at a collision or leaving the
vertical bounds (the env's `terminated`), or after `max_steps` control steps. The vehicle state
freezes once a trial is done, so per-step records past the end repeat the final pose.
"""

from __future__ import annotations

import time
from typing import Sequence

import numpy as np

from docrl_jax.evaluate.protocol import (DEFAULT_EVAL_ENV, DIRECTIONS, NOMINAL_YAW, SCENARIOS, TrialSpec,
                                         trial_starts)
from docrl_jax.evaluate.tables import summarize

_ENVS: dict = {}


def _eval_settings(max_steps: int, overrides: dict) -> dict:
    kw = dict(DEFAULT_EVAL_ENV)
    kw.update({k: tuple(v) if isinstance(v, list) else v for k, v in overrides.items()})
    kw["terminate_on_arrival"] = True
    kw["max_episode_steps"] = int(max_steps)
    return kw


def flown_env(vehicle: dict, env_overrides: dict) -> dict:
    """The env overrides a policy is evaluated under: its run's vehicle (`evaluate.run_dirs.run_vehicle`),
    then the command's --env (which wins: flying a policy in another vehicle is a test too)."""
    return {**vehicle, **env_overrides}


def make_eval_env(scenario: int, max_steps: int = 500, **overrides):
    """The environment of the evaluation: episodes end at arrival; `max_steps` steps at most.

    Cached per settings, so repeated evaluations in one process reuse the env and its compiled rollouts."""
    import docrl_jax.envs as envs
    kw = _eval_settings(max_steps, overrides)
    key = (int(scenario), tuple(sorted(kw.items())))
    if key not in _ENVS:
        _ENVS[key] = envs.make(scenario=scenario, **kw)
    return _ENVS[key]


def eval_params(scenario: int, max_steps: int = 500, **overrides):
    """The `EnvParams` of `make_eval_env(scenario, max_steps, **overrides)`, validated, without
    building the env (no MuJoCo model)."""
    from docrl_jax.envs import make_params
    return make_params(scenario, **_eval_settings(max_steps, overrides))


_ROLLOUTS: dict = {}


# What a rendering rollout records besides (`render=True`), per step and for the start: the pose and
# what the env knew (docrl_jax.envs.rendering draws them).
RENDER_RECORDS = ("qpos", "goal", "ranges", "vertical_ranges", "underwater", "distance")


def _cache_key(env, policy, max_steps: int, render: bool = False, from_states: bool = False) -> tuple:
    per_trial = None if policy.trial_params is None else repr(policy.trial_axes)   # the params' vmap axes
    return id(env), id(policy.act), id(policy.init_carry), int(max_steps), bool(render), bool(from_states), per_trial


def split_trial_key(key):
    """(reset key, policy key) of one trial's key: the reset key starts the env (`env.reset_to` draws
    the wind, the noise and the episode's plant from it), the policy key drives the policy."""
    import jax
    return jax.random.split(key)


def make_rollout(env, policy, max_steps: int, render: bool = False, from_states: bool = False):
    """jit(vmap(scan)) over trials: (params, keys (N,2), positions (N,3), yaws (N,), goal (3,)) -> records.

    Cached per (env, policy.act, max_steps, render, from_states, the per-trial params' axes), so calling
    again with other params or trials reuses the compiled function (a new N retraces once). `render=True` also records
    `RENDER_RECORDS` (N, T+1, ...) for the renderer (docrl_jax.evaluate.video) and takes one goal per
    trial (N, 3) (random starts and goals): the same trials, the same computation, a separate program
    so that the evaluator's own carries nothing more.

    `from_states=True`: (params, keys (N,2), states) -> records, where `states` is an `EnvState` with a
    leading trial axis (`reset_states`, `start_states`) and each key is the trial's policy key: the
    trials start from given states (a layout, a plant, a start drawn by `env.reset`) and run the same
    scan. The states must have this env's structure (its latency queues, procedural or not).

    A policy with `trial_params` (docrl_jax.policy) takes its params with a leading trial axis where its
    `trial_axes` say; `run_trials` and `run_from_states` make them from the trials' initial states.

    The policy's `info` is the env's with "step" the scan's own counter: the env's step count while a trial
    runs (trials start at step 0), the same for every trial, so under vmap it is one value for the batch and a
    `lax.cond` on it runs one branch, not both (the own map plans every few steps on it: envs.belief).
    """
    cache_key = _cache_key(env, policy, max_steps, render, from_states)
    if cache_key in _ROLLOUTS:
        return _ROLLOUTS[cache_key][0]
    import jax
    import jax.numpy as jnp

    def episode(params, k_policy, state0):
        carry0 = policy.init_carry()

        def body(c, x):
            state, pcarry, done = c
            k, t = x
            # info["step"]: the scan's counter, the env's own while the trial runs, unbatched (make_rollout's doc)
            pcarry, action = policy.act(params, pcarry, state.obs, {**state.info, "step": t}, k)
            new_state = env.step(state, action)
            keep = lambda new, old: jnp.where(done, old, new)
            next_state = jax.tree.map(keep, new_state, state)
            rec = {"position": next_state.info["position"], "underwater_before": state.info["underwater"],
                   "taken": ~done, "action": jnp.where(done, 0.0, jnp.asarray(action, jnp.float32)),
                   "reward": jnp.where(done, 0.0, new_state.reward)}
            if render:
                rec.update(_render_records(next_state))
            # The policy's carry goes on past the end: its actions there are dropped and the state stays frozen.
            return (next_state, pcarry, done | new_state.done), rec

        xs = (jax.random.split(k_policy, max_steps), jnp.arange(max_steps, dtype=jnp.int32))
        (final, _, _), rec = jax.lax.scan(body, (state0, carry0, jnp.zeros((), bool)), xs)
        info = final.info
        out = {
            "positions": jnp.concatenate([state0.info["position"][None], rec["position"]], 0),
            "underwater_before": rec["underwater_before"], "taken": rec["taken"], "actions": rec["action"],
            "rewards": rec["reward"],
            "arrived": info["arrived"], "collision": info["collision"], "out_of_bounds": info["out_of_bounds"],
            "terminated": info["terminated"], "final_distance": info["distance"],
        }
        if render:
            first = _render_records(state0)
            out.update({k: jnp.concatenate([first[k][None], rec[k]], 0) for k in RENDER_RECORDS})
        return out

    def one_trial(params, key, position, yaw, goal):
        k_reset, k_policy = split_trial_key(key)
        return episode(params, k_policy, env.reset_to(k_reset, position, yaw, goal))

    axes = None if policy.trial_params is None else policy.trial_axes   # params shared, or each trial's own
    if from_states:
        fn = jax.jit(jax.vmap(episode, in_axes=(axes, 0, 0)))
    else:
        fn = jax.jit(jax.vmap(one_trial, in_axes=(axes, 0, 0, 0, 0 if render else None)))
    _ROLLOUTS[cache_key] = (fn, env, policy)  # keep env/policy alive so the ids stay unique
    return fn


def _render_records(state) -> dict:
    return {"qpos": state.sim.data.qpos, "goal": state.sim.goal, "ranges": state.info["ranges"],
            "vertical_ranges": state.info["vertical_ranges"],
            "underwater": state.info["underwater"], "distance": state.info["distance"]}


def run_trials(env, policy, start, goal, key, num_trials: int, max_steps: int = 500,
               yaw: float = 0.0, spec: TrialSpec = TrialSpec(), render: bool = False,
               plants_of=None) -> dict[str, np.ndarray]:
    """Runs `num_trials` trials of `policy` from (jittered) `start` to `goal` as one vmapped rollout.

    Returns numpy arrays, leading axis = trial: positions (N, T+1, 3) (frozen after the end),
    steps (N,), outcome (N,) index into OUTCOMES, t_air/t_water/time (N,) simulated seconds,
    path_length (N,), success/collision/out_of_bounds/timeout/diverged (N,) bool, final_distance,
    episode_return, start_positions (N, 3), start_yaws (N,), and the raw per-step records; with
    `render`, also `RENDER_RECORDS` (N, T+1, ...) (see `make_rollout`).

    `plants_of` (an `EnvParams`): each trial's plant (true vehicle, water, wind, sensors, delays) is
    the one an env of those parameters draws from the trial's key (`plants_for`), `env` does all
    else. These are the trials `run_trials(env_of_those_params, ...)` runs, from one compiled program
    for every plant `env`'s structure admits (its latency queues, whether range noise and dropouts
    are drawn): the robustness benchmark's perturbations (docrl_jax.evaluate.robustness). They run
    from states (`start_states`, `make_rollout(from_states=True)`).
    """
    import jax
    _check_trials(env, num_trials, max_steps, "run_trials")
    k_start, k_trials = jax.random.split(key)
    positions, yaws = trial_starts(k_start, start, num_trials, yaw, spec)
    keys = jax.random.split(k_trials, num_trials)
    goal = jax.numpy.asarray(goal, jax.numpy.float32)
    if _from_start_states(policy, plants_of):
        k_reset, k_policy = jax.vmap(split_trial_key, out_axes=1)(keys)
        goals = jax.numpy.broadcast_to(goal, (num_trials, 3))
        plants = None if plants_of is None else plants_for(plants_of, k_reset)
        states = start_states(env, k_reset, positions, yaws, goals, plants)
        return _from_states(env, policy, states, k_policy, max_steps, render, positions, yaws)
    fn = make_rollout(env, policy, max_steps, render)
    if render:
        goal = jax.numpy.broadcast_to(goal, (num_trials, 3))
    out = jax.device_get(fn(policy.params, keys, positions, yaws, goal))
    out = {k: np.asarray(v) for k, v in out.items()}
    return trial_metrics(out, env.control_dt, np.asarray(positions), np.asarray(yaws))


def _from_start_states(policy, plants_of) -> bool:
    """Whether `run_trials` starts its trials from states made first (`start_states`) rather than inside
    the rollout: for given plants, and for a policy whose params are made from the trials' states."""
    return plants_of is not None or policy.trial_params is not None


def _check_trials(env, num_trials: int, max_steps: int, what: str) -> None:
    if not getattr(env.params, "terminate_on_arrival", False):
        raise ValueError(f"{what} needs an env with terminate_on_arrival=True (use make_eval_env)")
    if num_trials <= 0:
        raise ValueError(f"num_trials={num_trials}: must be a positive integer")
    if max_steps <= 0:
        raise ValueError(f"max_steps={max_steps}: must be a positive integer")


def run_from_states(env, policy, states, keys, max_steps: int = 500, render: bool = False) -> dict[str, np.ndarray]:
    """Trials of `policy` from given initial states (an `EnvState` with a leading trial axis, e.g.
    `reset_states`), one policy key each (N, 2), as one vmapped rollout of `env`; the arrays of
    `run_trials`, the start poses read from the states."""
    n = int(np.shape(keys)[0])
    _check_trials(env, n, max_steps, "run_from_states")
    return _from_states(env, policy, states, keys, max_steps, render, states.info["position"], states.info["yaw"])


def _from_states(env, policy, states, keys, max_steps, render, start_positions, start_yaws):
    import jax
    fn = make_rollout(env, policy, max_steps, render, from_states=True)
    params = policy.params if policy.trial_params is None else policy.trial_params(policy.params, env, states)
    out = jax.device_get(fn(params, keys, states))
    out = {k: np.asarray(v) for k, v in out.items()}
    return trial_metrics(out, env.control_dt, np.asarray(start_positions), np.asarray(start_yaws))


_STARTS: dict = {}   # (id(env), kind) -> (jit(vmap(env.reset or env.reset_to)), env)


def _start_fn(env, kind: str):
    import jax
    if (id(env), kind) not in _STARTS:   # compiled once per env (keeping the env alive keeps its id unique)
        if kind == "reset":
            fn = lambda k, layout, plant: env.reset(k, layout=layout, plant=plant)  # noqa: E731
        else:
            fn = lambda k, p, y, g, plant: env.reset_to(k, p, y, g, plant=plant)  # noqa: E731
        _STARTS[(id(env), kind)] = (jax.jit(jax.vmap(fn)), env)
    return _STARTS[(id(env), kind)][0]


def reset_states(env, keys, layouts=None, plants=None):
    """`env.reset(key, layout, plant)` of each key (N, 2) as one jit(vmap): random starts, goals and
    yaws of the env's reset distribution; `layouts` (a `layouts.Layout` with a leading trial axis,
    e.g. held-out layouts) for a procedural tank, `plants` (an `envs.physics.Plant` with a leading
    axis) instead of the env's own draw. Compiled once per env."""
    return _start_fn(env, "reset")(keys, layouts, plants)


def start_states(env, keys, positions, yaws, goals, plants=None):
    """`env.reset_to(key, position, yaw, goal, plant=plant)` per trial (leading axis N) as one
    jit(vmap); compiled once per env."""
    return _start_fn(env, "reset_to")(keys, positions, yaws, goals, plants)


def plants_for(params, reset_keys):
    """The plants an env with `params` draws at `env.reset_to(k, ...)` for each reset key k (N, 2): the
    domain randomisation's draw from the key folded with 2, as `HUAUVEnv.reset_to` draws it (a test
    checks the two agree)."""
    import jax
    from docrl_jax.envs import randomization
    return jax.vmap(lambda k: randomization.sample_plant(jax.random.fold_in(k, 2), params))(reset_keys)


def trial_metrics(out: dict[str, np.ndarray], dt: float, start_positions, start_yaws) -> dict[str, np.ndarray]:
    """Per-trial metrics from the rollout's records (`run_trials` documents them).

    A control step counts as air or water by the vehicle's medium at the start of the step, so
    t_air + t_water is exactly the trial time (steps * dt); the path length sums the per-step
    displacements of the steps taken."""
    taken = out["taken"].astype(bool)                       # (N, T)
    water = out["underwater_before"].astype(bool)
    steps = taken.sum(1)
    success = out["arrived"].astype(bool)
    collision = out["collision"].astype(bool) & ~success
    oob = out["out_of_bounds"].astype(bool) & ~success & ~collision
    diverged = out["terminated"].astype(bool) & ~success & ~collision & ~oob
    timeout = ~success & ~out["terminated"].astype(bool)
    outcome = np.select([success, collision, oob, timeout, diverged], [0, 1, 2, 3, 4], 4)
    disp = np.linalg.norm(np.diff(out["positions"], axis=1), axis=-1)   # (N, T), zero after the end
    res = dict(out)
    res.update(
        steps=steps, time=steps * dt, t_air=(taken & ~water).sum(1) * dt, t_water=(taken & water).sum(1) * dt,
        path_length=(disp * taken).sum(1), success=success, collision=collision, out_of_bounds=oob,
        timeout=timeout, diverged=diverged, outcome=outcome, episode_return=out["rewards"].sum(1),
        start_positions=start_positions, start_yaws=start_yaws)
    return res


def trial_key(seed: int, scenario: int, direction: str):
    """The PRNG key of the trials of one (scenario, direction): a function of (seed, scenario,
    direction) only, so every method and seed index meets the same wind, noise and start jitter, and
    the renderer (docrl_jax.evaluate.video) draws the very trials the evaluator ran."""
    import jax
    return jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), scenario), DIRECTIONS.index(direction))


def evaluate_policy(policy, method: str = "policy", scenarios: Sequence[int] = SCENARIOS,
                    directions: Sequence[str] = DIRECTIONS, num_trials: int = 100, max_steps: int = 500,
                    seed: int = 0, env_overrides: dict | None = None, seed_index: int | None = None,
                    on_result=None) -> list[tuple[dict, dict]]:
    """The whole protocol for one policy: for each scenario and direction, `num_trials` trials.

    Returns [(row, trials)]: `row` = `summarize` plus method, seed_index, scenario, direction and the
    seconds taken (`compile_s` when this call compiled the rollout, else `run_s`); `trials` = the
    `run_trials` arrays. The trial seeds depend only on (seed, scenario, direction), so every method
    and seed index meets the same wind, noise and start jitter. `on_result(row, trials, env, start,
    goal)` is called after each (scenario, direction)."""
    import docrl_jax.envs as envs
    results = []
    for scenario in scenarios:
        env = make_eval_env(scenario, max_steps, **(env_overrides or {}))
        for direction in directions:
            start, goal = envs.eval_pair(scenario, direction)
            key = trial_key(seed, scenario, direction)
            fresh = _cache_key(env, policy, max_steps, from_states=_from_start_states(policy, None)) not in _ROLLOUTS
            t0 = time.time()
            trials = run_trials(env, policy, start, goal, key, num_trials, max_steps, NOMINAL_YAW[direction])
            elapsed = round(time.time() - t0, 2)
            row = {"method": method, "seed_index": seed_index, "scenario": scenario, "direction": direction,
                   **summarize(trials), "compile_s": elapsed if fresh else None, "run_s": None if fresh else elapsed}
            if on_result is not None:
                on_result(row, trials, env, start, goal)
            results.append((row, trials))
    return results


# ------------------------------------------------------------------ trips: the robustness benchmark's and the tank trials'
# (start_water_fraction, goal_water_fraction) of the random and layout trips per direction.
MEDIA = {"air_to_water": (0.0, 1.0), "water_to_air": (1.0, 0.0)}
MEDIA_KEYS = ("start_water_fraction", "goal_water_fraction")
# Trip keys: fold_in(fold_in(fold_in(fold_in(PRNGKey(seed), salt), scenario), direction), trial).
TRIP_SALT = {"random_trips": 0x7269, "held_out_layouts": 0x6C61, "structured": 0x7374, "tanks": 0x746B}


def trip_keys(seed: int, test: str, scenario: int, direction: str, num_trials: int):
    """(N, 2) keys of the random or layout trips: trial i's depends on (seed, test, scenario, direction,
    i) only, not on N or the method."""
    import jax
    import jax.numpy as jnp
    base = jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(seed), TRIP_SALT[test]), scenario)
    base = jax.random.fold_in(base, DIRECTIONS.index(direction))
    return jax.vmap(lambda i: jax.random.fold_in(base, i))(jnp.arange(num_trials))


def trip_trials(host, sampler, policy, keys, nominal_params, max_steps: int, layouts=None,
                render: bool = False) -> dict:
    """Trips from `sampler.reset(key, layout)` (the host's env with the media forced), the plant an env
    of `nominal_params` draws, run by the host's rollout; `run_from_states`' arrays plus `goals` (N, 3)."""
    import dataclasses

    import jax
    media = {k: getattr(host.params, k) for k in MEDIA_KEYS}
    if dataclasses.replace(sampler.params, **media) != host.params:   # its states would not be the host's
        raise ValueError("trip_trials: the sampler env differs from the host env in more than the media")
    k_reset, k_policy = jax.vmap(split_trial_key, out_axes=1)(keys)
    states = reset_states(sampler, k_reset, layouts, plants_for(nominal_params, k_reset))
    trials = run_from_states(host, policy, states, k_policy, max_steps, render)
    trials["goals"] = np.asarray(jax.device_get(states.info["goal"]))
    return trials
