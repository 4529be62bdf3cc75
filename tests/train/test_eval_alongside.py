"""Evaluations alongside training (train.eval_alongside): the evaluation lanes of the chunk give the
evaluation program's results on the same policy and key, keep the policy they began with, and a run
writes each evaluation's rows once, in order, also when a stop finishes one with the program.

The reference is the evaluation program (docrl_jax.train.evaluation.evaluate), which steps its own
env (episodes end at arrival) in a while loop of its own; the lanes run in the training env under
auto-reset. A trained policy (tests/data/trained) gives successes and a collision, the untrained one
collisions, so the outcomes compared are not all alike. No gradient updates (updates_per_step 0):
the policies stay as given, and the programs compile in ~30 s on 2 CPU cores. The fixture also records
the order in which they reach XLA's compiler (the chunk first)."""

from __future__ import annotations

import csv
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.config import load_config
from docrl_jax.runs import load_policy
from docrl_jax.train.run import run
from docrl_jax.train.evaluation import eval_keys
from docrl_jax.train import program_store
from docrl_jax.train.program_store import compile_lowered
from docrl_jax.train.programs import compile_programs

TRAINED = Path(__file__).resolve().parents[1] / "data" / "trained" / "td3_lstm"
# Chunks of 100 iterations of 4 training envs and 36 evaluation lanes (12 episodes x 3 groups). The
# training env ends its episodes at a fan range of 0.95 m (a collision margin of 0.45, wider than
# td3_lstm's, so that the pairs' flights past the risers would end at it); the evaluations run without.
SETS = ["env.num_envs=4", "train.updates_per_step=0", "train.eval_episodes=12", "train.log_every=400",
        "train.eval_alongside=true", "train.start_steps=100", "train.total_env_steps=4800",
        "train.eval_every=400", "train.checkpoint_every=2000", "env.collision_margin=0.45", "env.goal_clearance=1.0"]


@pytest.fixture(scope="module")
def setup():
    config = load_config("td3_lstm", SETS)
    handed = []   # what programs._compile handed to XLA's compile, in order

    def spy(lowered, platform, options=None):
        handed.append(lowered)
        return compile_lowered(lowered, platform, options)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(program_store, "compile_lowered", spy)
        programs, _ = compile_programs(config)

    def fresh():  # a new runner state (a chunk donates the one it is given)
        return programs.init(jnp.stack([jax.random.PRNGKey(0)]), jnp.int32(config.train.total_env_steps))

    policies = {"trained": jax.tree.map(lambda x: jnp.asarray(x)[None], load_policy(TRAINED).params),
                "untrained": jax.tree.map(jnp.copy, fresh().agent.actor_average)}
    return programs, fresh, policies, handed


def _alongside(programs, state, params, key, swap_to=None, starts=None):
    """Begins an evaluation of `params` in the lanes and runs chunks until its last episode ended;
    `swap_to` replaces the run's policy after the first chunk (the lanes must not see it); `starts`
    replaces the episodes' first states that eval_starts makes from `key`."""
    starts = programs.eval_starts(key) if starts is None else starts
    state = state.replace(agent=state.agent.replace(actor_average=jax.tree.map(jnp.copy, params)),
                          evals=state.evals.replace(begin=jnp.ones(1, bool), fresh=starts))
    for i in range(6):  # at most 500 steps: five chunks of 100
        state, m = programs.chunk(state)
        out = jax.device_get(m["evaluation"])
        if out["running"][0] == 0:
            return state, {k: v for k, v in out.items() if k != "running"}
        if swap_to is not None and i == 0:
            state = state.replace(agent=state.agent.replace(actor_average=jax.tree.map(jnp.copy, swap_to)))
    raise AssertionError("the evaluation lanes never finished")


def _assert_same(lanes: dict, program: dict):
    assert set(lanes) == set(program)
    for k in program:
        if k == "episode_return":
            np.testing.assert_allclose(lanes[k], program[k], rtol=1e-5)
        else:  # fractions of 12 episodes: the same episodes end the same way
            np.testing.assert_array_equal(lanes[k], program[k], err_msg=k)


def test_lanes_give_the_evaluation_programs_results(setup):
    programs, fresh, policies, _ = setup
    state, key = fresh(), eval_keys([0], 7)
    results = {}
    for name, params in policies.items():
        state, lanes = _alongside(programs, state, params, key)
        program = jax.device_get(programs.evaluate(params, key))
        _assert_same(lanes, program)
        results[name] = program
    # The two policies end their episodes differently, so equal results are not a coincidence.
    assert results["trained"]["success_air_to_water"][0] == 1.0 and results["trained"]["success_rate"][0] >= 0.9
    assert results["untrained"]["success_rate"][0] == 0.0 and results["untrained"]["collision_air_to_water"][0] == 1.0
    # Another key draws other episodes: the lanes follow the key they were given.
    other = eval_keys([0], 8)
    _, lanes = _alongside(programs, state, policies["trained"], other)
    _assert_same(lanes, jax.device_get(programs.evaluate(policies["trained"], other)))


def test_lanes_fly_without_the_training_margins(setup):
    """The lanes' episodes start with the training-only margins cleared, so they end where the evaluation
    program's env (without margins) ends them (the test above); with the margins left on, the same
    episodes of the same policy would end otherwise."""
    programs, fresh, policies, _ = setup
    key = eval_keys([0], 7)
    starts = programs.eval_starts(key)
    assert starts.sim.training_margins.shape == (1, 36) and not np.any(starts.sim.training_margins)
    assert np.all(fresh().env.sim.training_margins[0, :4])   # the training envs' own episodes keep them
    kept = starts.replace(sim=starts.sim.replace(training_margins=jnp.ones_like(starts.sim.training_margins)))
    _, lanes = _alongside(programs, fresh(), policies["trained"], key, starts=kept)
    program = jax.device_get(programs.evaluate(policies["trained"], key))
    assert program["success_air_to_water"][0] == 1.0
    assert lanes["success_air_to_water"][0] < 1.0 and lanes["collision_air_to_water"][0] > 0.0


def test_lanes_keep_the_policy_they_began_with(setup):
    """The run's policy changes while an evaluation runs (it learns); the lanes keep their copy."""
    programs, fresh, policies, _ = setup
    key = eval_keys([0], 9)
    _, lanes = _alongside(programs, fresh(), policies["trained"], key, swap_to=policies["untrained"])
    _assert_same(lanes, jax.device_get(programs.evaluate(policies["trained"], key)))
    assert lanes["success_rate"][0] >= 0.9


def test_the_chunk_is_lowered_and_handed_to_the_compiler_first(setup):
    """programs._compile hands XLA each program as soon as it is lowered, the training chunk (the longest
    compile) first, so it compiles while the rest are lowered; init and the lanes' first states follow
    (and the evaluation, unless this process had compiled it)."""
    programs, _, _, handed = setup
    assert all(isinstance(lowered, jax.stages.Lowered) for lowered in handed)
    takes_the_state = [jax.tree.structure(lowered.args_info[0][0]) == jax.tree.structure(programs.state_shape)
                       for lowered in handed]
    assert takes_the_state[0] and not any(takes_the_state[1:]) and len(handed) in (3, 4)


def _rows(run_dir: Path) -> list[dict]:
    with open(run_dir / "metrics.csv") as fh:
        return list(csv.DictReader(fh))


def test_a_run_writes_each_evaluation_once_also_when_stopped_and_resumed(setup, tmp_path):
    """12 chunks, an evaluation due after every chunk, each taking up to 5 chunks (the untrained
    policy's episodes): evaluations wait for the running one, rows come in order, once each, the last
    at the end. Stopped after 7 chunks, the running evaluation is finished by the program before the
    checkpoint; its row equals the uninterrupted run's (same policy, same key), and the resumed run
    adds no second row for any step."""
    config = load_config("td3_lstm", SETS)
    whole = tmp_path / "whole"
    assert run(config, whole, show_progress=False) == 0
    rows = _rows(whole)
    steps = [int(r["env_steps"]) for r in rows]
    assert steps[0] == 0 and steps[-1] == 4800 and steps == sorted(set(steps))
    assert 3 <= len(steps) < 13   # fewer than one per chunk: due evaluations waited for the running one
    parted = tmp_path / "parted"
    assert run(config, parted, show_progress=False, stop_after_chunks=7) == 130
    stopped = [int(r["env_steps"]) for r in _rows(parted)]
    # Up to the stop the two runs are one: the stopped run's rows are the first of the whole run's, the
    # last of them the evaluation that was running at the stop, then the one due at the stop itself
    # (every chunk boundary is due here), both run by the program before the checkpoint.
    assert stopped[-1] == 2800 and stopped[:-1] == [s for s in steps if s <= stopped[-2]]
    assert run(config, parted, resume=True, show_progress=False) == 0
    resumed = _rows(parted)
    resumed_steps = [int(r["env_steps"]) for r in resumed]
    assert resumed_steps == sorted(set(resumed_steps)) and resumed_steps[-1] == 4800
    both = set(resumed_steps) & set(steps)
    assert {0, 4800} <= both
    by_step = {int(r["env_steps"]): r for r in rows}
    for r in resumed:  # the same evaluations, however they were run (lanes, or the program at a stop)
        s = int(r["env_steps"])
        if s in both:
            for k in ("success_rate", "success_air_to_water", "success_water_to_air", "episode_return",
                      "collision_air_to_water", "collision_water_to_air"):
                assert float(r[k]) == pytest.approx(float(by_step[s][k]), rel=1e-5), (s, k)
