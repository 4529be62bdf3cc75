"""Evaluations alongside training (train.eval_alongside): the evaluation lanes of the chunk give the
evaluation program's results on the same policy and key, keep the policy they began with, the paper
pairs begin new evaluations while the random goals of an earlier one run, and a run writes each
evaluation's rows once, also when a stop finishes those running with the program.

The reference is the evaluation program (docrl_jax.train.evaluation.evaluate), which steps its own
env (episodes end at arrival) in a while loop of its own; the lanes run in the training env under
auto-reset. A trained policy (tests/data/trained) gives successes and a collision, the untrained one
collisions, so the outcomes compared are not all alike. No gradient updates (updates_per_step 0):
the policies stay as given, and the programs compile in ~30 s on 2 CPU cores."""

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
from docrl_jax.train.programs import compile_programs

TRAINED = Path(__file__).resolve().parents[1] / "data" / "trained" / "td3_lstm"
# Chunks of 100 iterations of 4 training envs and 36 evaluation lanes (12 episodes x 3 groups).
SETS = ["env.num_envs=4", "train.updates_per_step=0", "train.eval_episodes=12", "train.log_every=400",
        "train.eval_alongside=true", "train.start_steps=100", "train.total_env_steps=4800",
        "train.eval_every=400", "train.checkpoint_every=2000"]


@pytest.fixture(scope="module")
def setup():
    config = load_config("td3_lstm", SETS)
    programs, _ = compile_programs(config)

    def fresh():  # a new runner state (a chunk donates the one it is given)
        return programs.init(jnp.stack([jax.random.PRNGKey(0)]), jnp.int32(config.train.total_env_steps))

    policies = {"trained": jax.tree.map(lambda x: jnp.asarray(x)[None], load_policy(TRAINED).params),
                "untrained": jax.tree.map(jnp.copy, fresh().agent.actor_average)}
    return programs, fresh, policies


def _alongside(programs, state, params, key, swap_to=None):
    """Begins an evaluation of `params` in the lanes and runs chunks until its last episode ended;
    `swap_to` replaces the run's policy after the first chunk (the lanes must not see it)."""
    state = state.replace(agent=state.agent.replace(actor_average=jax.tree.map(jnp.copy, params)),
                          evals=state.evals.replace(begin=jnp.ones((1, 3), bool), fresh=programs.eval_starts(key)))
    for i in range(6):  # at most 500 steps: five chunks of 100
        state, m = programs.chunk(state)
        out = jax.device_get(m["evaluation"])
        if not out["running"][0].any():
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
    programs, fresh, policies = setup
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


def test_lanes_keep_the_policy_they_began_with(setup):
    """The run's policy changes while an evaluation runs (it learns); the lanes keep their copy."""
    programs, fresh, policies = setup
    key = eval_keys([0], 9)
    _, lanes = _alongside(programs, fresh(), policies["trained"], key, swap_to=policies["untrained"])
    _assert_same(lanes, jax.device_get(programs.evaluate(policies["trained"], key)))
    assert lanes["success_rate"][0] >= 0.9


def _rows(run_dir: Path) -> list[dict]:
    with open(run_dir / "metrics.csv") as fh:
        return list(csv.DictReader(fh))


def test_a_run_writes_each_evaluation_once_also_when_stopped_and_resumed(setup, tmp_path):
    """12 chunks, an evaluation due after every chunk, each taking up to 5 chunks (the untrained
    policy's episodes): evaluations wait for the running pairs, rows come once each, the last at the
    end, and one began while the random goals of an earlier one ran evaluates the pairs only (its
    random-goal columns NaN). Stopped after 7 chunks, the running evaluations are finished by the
    program before the checkpoint; their rows equal the uninterrupted run's (same policy, same key), and
    the resumed run adds no second row for any step."""
    config = load_config("td3_lstm", SETS)
    whole = tmp_path / "whole"
    assert run(config, whole, show_progress=False) == 0
    rows = _rows(whole)
    steps = [int(r["env_steps"]) for r in rows]
    assert steps[0] == 0 and steps[-1] == 4800 and len(steps) == len(set(steps))
    assert 3 <= len(steps) < 13   # fewer than one per chunk: due evaluations waited for the running pairs
    pairs_only = [int(r["env_steps"]) for r in rows if np.isnan(float(r["success_rate"]))]
    assert pairs_only and all(np.isfinite(float(r["success_air_to_water"])) for r in rows)
    parted = tmp_path / "parted"
    assert run(config, parted, show_progress=False, stop_after_chunks=7) == 130
    stopped = [int(r["env_steps"]) for r in _rows(parted)]
    # Up to the stop the two runs are one: the stopped run's rows are the first of the whole run's, the
    # last of them the evaluation that was running at the stop, then the one due at the stop itself
    # (every chunk boundary is due here), both run by the program before the checkpoint.
    assert stopped[-1] == 2800 and sorted(stopped[:-1]) == [s for s in steps if s <= max(stopped[:-1])]
    assert run(config, parted, resume=True, show_progress=False) == 0
    resumed = _rows(parted)
    resumed_steps = [int(r["env_steps"]) for r in resumed]
    assert len(resumed_steps) == len(set(resumed_steps)) and resumed_steps[-1] == 4800
    both = set(resumed_steps) & set(steps)
    assert {0, 4800} <= both
    by_step = {int(r["env_steps"]): r for r in rows}
    for r in resumed:  # the same evaluations, however they were run (lanes, or the program at a stop)
        s = int(r["env_steps"])
        if s in both:
            for k in ("success_rate", "success_air_to_water", "success_water_to_air", "episode_return",
                      "collision_air_to_water", "collision_water_to_air"):
                a, b = float(r[k]), float(by_step[s][k])   # the random goals may have run in one run only
                assert a == pytest.approx(b, rel=1e-5) or np.isnan(a) or np.isnan(b), (s, k)


def test_pairs_begin_while_the_random_goals_of_an_earlier_evaluation_run():
    """The host's side alone (docrl_jax.train.loop.Evaluations, no program compiled): lane groups
    [random goals, A-W, W-A] of one seed; the lanes' params say which group holds which policy."""
    import dataclasses
    from types import SimpleNamespace
    from docrl_jax.train.loop import Evaluations

    @dataclasses.dataclass(frozen=True)
    class Lanes:
        begin: np.ndarray
        params: np.ndarray   # (seeds, groups): a policy id per group
        fresh: object = None

        def replace(self, **kw):
            return dataclasses.replace(self, **kw)

    @dataclasses.dataclass(frozen=True)
    class State:
        evals: Lanes
        agent: object = dataclasses.field(default_factory=lambda: SimpleNamespace(updates=np.zeros(1)))

        def replace(self, **kw):
            return dataclasses.replace(self, **kw)

    def chunk_results(running, trips=None, pairs=None):
        ev = {"running": np.array([running])}
        if trips is not None:
            ev.update(success_rate=np.array([trips]), episode_return=np.array([-trips]))
        if pairs is not None:
            for d, v in zip(("air_to_water", "water_to_air"), pairs):
                ev.update({f"success_{d}": np.array([v]), f"collision_{d}": np.array([1 - v]),
                           f"out_of_bounds_{d}": np.array([0.0])})
        return {"evaluation": ev}

    recorded, evaluated = [], []

    def evaluate(params, keys):
        evaluated.append(int(params[0]))
        return {k: v for k, v in chunk_results([0, 0, 0], 0.5, (0.25, 0.75))["evaluation"].items() if k != "running"}

    programs = SimpleNamespace(evaluate=evaluate, eval_starts=lambda keys: "fresh")
    placement = SimpleNamespace(get=lambda x: x, put_seeds=lambda x: x)
    hooks = SimpleNamespace(record=lambda steps, taken, updates, ev, trained, policy:
                            recorded.append((steps, dict(ev), int(policy()[0]))))
    evals = Evaluations(programs, placement, [0], hooks)
    state = State(Lanes(np.zeros((1, 3), bool), np.array([[0, 0, 0]])))

    state, began = evals.begin(state, 0)       # all groups free: the whole evaluation
    assert began and state.evals.begin.tolist() == [[True, True, True]]
    state = state.replace(evals=state.evals.replace(params=np.array([[1, 1, 1]]), begin=np.zeros((1, 3), bool)))
    evals.collect(state, chunk_results([5, 0, 0], pairs=(0.5, 0.6)))   # the pairs ended, the random goals run
    assert recorded == []
    state, began = evals.begin(state, 400)     # the pairs begin again, alone
    assert began and state.evals.begin.tolist() == [[False, True, True]]
    state = state.replace(evals=state.evals.replace(params=np.array([[1, 2, 2]])))
    evals.collect(state, chunk_results([3, 0, 0], pairs=(0.7, 0.8)))
    assert [r[0] for r in recorded] == [400] and recorded[0][2] == 2
    assert set(recorded[0][1]) == {"success_air_to_water", "success_water_to_air", "collision_air_to_water",
                                   "collision_water_to_air", "out_of_bounds_air_to_water",
                                   "out_of_bounds_water_to_air"} and recorded[0][1]["success_air_to_water"][0] == 0.7
    state, _ = evals.begin(state, 800)
    state = state.replace(evals=state.evals.replace(params=np.array([[1, 3, 3]])))
    assert evals.begin(state, 1200) == (state, False)   # the pairs of 800 still run
    evals.collect(state, chunk_results([0, 2, 2], trips=0.2, pairs=(0.0, 0.0)))  # the random goals of 0 end
    steps, ev, policy = recorded[1]
    assert (steps, policy) == (0, 1) and ev["success_rate"][0] == 0.2 and ev["success_air_to_water"][0] == 0.5
    evals.finish(state)                       # 800, its pairs still running: the program on its policy
    assert evaluated == [3] and recorded[2][0] == 800 and "success_rate" not in recorded[2][1]
    assert recorded[2][1]["success_water_to_air"][0] == 0.75 and evals.running == []
