"""The trainer end to end on CPU: outputs of a run, resume, vmapped seeds, what the replay stores
while acting, load_policy and its errors, the command line's refusals, non-finite losses."""

from __future__ import annotations

import csv
import dataclasses
import re
import shutil
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml
from _trainer_common import easy_config, finished_run, tmp_dir

from docrl_jax import checkpoint
from docrl_jax.train import cli, programs
from docrl_jax.train import run as train_run
from docrl_jax.train.programs import compile_programs
from docrl_jax.config import config_from_dict
from docrl_jax.errors import RunDirError
from docrl_jax.policy import Policy
from docrl_jax.train import load_policy, make_trainer


def _rows(run_dir):
    with open(run_dir / "metrics.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _total(config):
    return jnp.asarray(make_trainer(config).total_env_steps, jnp.int32)


def test_run_writes_config_metrics_tensorboard_and_checkpoints():
    d = finished_run()
    assert config_from_dict(yaml.safe_load((d / "config.yaml").read_text())) == easy_config()
    rows = _rows(d)
    for col in ("env_steps", "wall_time_s", "seed", "success_rate", "episode_return"):
        assert col in rows[0]
    assert [int(r["env_steps"]) for r in rows] == [0, 8000, 16000]
    assert {r["seed"] for r in rows} == {"0"}
    walls = [float(r["wall_time_s"]) for r in rows]
    assert walls == sorted(walls) and walls[0] > 0
    assert all(0.0 <= float(r["success_rate"]) <= 1.0 for r in rows)
    assert int(rows[-1]["grad_updates"]) == (16000 - 2000) // 16 * 2
    assert list((d / "tb").glob("events.out.tfevents.*"))
    assert sorted(int(p.name) for p in (d / "checkpoints").iterdir() if p.name.isdigit()) == [8000, 16000]


def test_resume_gives_the_same_metrics_as_an_uninterrupted_run():
    d = tmp_dir("resume")
    config = easy_config()
    # Interrupt after 1 chunk (4,000 steps: between evaluations), then after 2 more, then finish.
    assert train_run.run(config, d, show_progress=False, stop_after_chunks=1) == cli.EXIT_INTERRUPTED
    assert checkpoint.latest_step(d) == 4000
    assert train_run.run(config, d, resume=True, show_progress=False, stop_after_chunks=2) == cli.EXIT_INTERRUPTED
    assert checkpoint.latest_step(d) == 12000
    assert train_run.run(config, d, resume=True, show_progress=False) == cli.EXIT_OK
    strip = lambda rows: [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]
    assert strip(_rows(d)) == strip(_rows(finished_run()))
    a, b = load_policy(d, which="final"), load_policy(finished_run(), which="final")   # the trained actor itself
    jax.tree.map(lambda x, y: np.testing.assert_array_equal(np.asarray(x), np.asarray(y)), a.params, b.params)


def test_vmapped_seeds_equal_separate_runs():
    """Seed i of a vmapped run is the same computation as a separate run of seed i. Bit equality is
    not expected: under vmap XLA batches the matmuls differently, and RL amplifies float32 rounding
    chaotically over thousands of updates (measured after one chunk of 1,750 updates: identical
    episode counts, losses within 2.2e-4 relative, single weights a few Adam steps apart). So one
    chunk is compared: counts exactly, losses to 1e-3 relative, and each parameter tensor of seed i
    must be at least 10x closer to seed i's separate run than the two seeds' runs are to each other."""
    two = easy_config(train__num_seeds=2, train__seed=3)
    # The run's 2-seed init and chunk as compile_programs builds them, without the 2-seed evaluation
    # it would compile too (this test: 32 -> 24 s here), which no test runs.
    init2, chunk2 = programs.jitted_programs(programs.program_config(two, False), (jax.devices()[0],), False)[:2]
    init1, chunk1 = compile_programs(easy_config())[0][:2]
    total = _total(two)
    s2, m2 = chunk2(init2(jnp.stack([jax.random.PRNGKey(3), jax.random.PRNGKey(4)]), total))
    m2 = jax.device_get(m2)
    separate = []
    for i, seed in enumerate((3, 4)):
        s1, m1 = chunk1(init1(jax.random.PRNGKey(seed)[None], total))
        for k, v in jax.device_get(m1).items():
            np.testing.assert_allclose(v[0], m2[k][i], rtol=1e-3, atol=1e-5, err_msg=k)
        for k in ("episodes", "success_sum", "arrivals", "collisions", "updates", "actor_updates"):
            assert m1[k][0] == m2[k][i], k
        separate.append(jax.tree.map(lambda x: np.asarray(x)[0], s1.agent.actor))
    vmapped = [jax.tree.map(lambda x, i=i: np.asarray(x)[i], s2.agent.actor) for i in (0, 1)]
    for i in (0, 1):
        for same, sep, other in zip(jax.tree.leaves(vmapped[i]), jax.tree.leaves(separate[i]),
                                    jax.tree.leaves(separate[1 - i])):
            gap, between = np.linalg.norm(same - sep), np.linalg.norm(sep - other)
            assert gap < 0.1 * between, (gap, between)

def test_replay_stores_the_acting_carry_reset_at_episode_start():
    config = easy_config()
    init, chunk = compile_programs(config)[0][:2]
    state = init(jax.random.PRNGKey(0)[None], _total(config))
    params = jax.device_get(jax.tree.map(lambda x: x[0], state.agent.actor))  # before the chunk donates it
    state, _ = chunk(state)
    data = jax.device_get(jax.tree.map(lambda x: x[0], state.buffer.data))
    actor = make_trainer(config).agent.actor
    apply = jax.jit(actor.apply)
    start, carry, obs = data["start"], data["carry"], data["obs"]
    done = data["terminated"] | data["truncated"]
    assert start[:, 0].all() and not np.any(carry[0][:, 0]) and not np.any(carry[1][:, 0])
    # Steps 0..124 acted with the initial params (updates start after 2,000 env steps = 125 iterations).
    assert done[:, :125].any() and (~start[:, 1:126]).any()
    for t in range(125):
        np.testing.assert_array_equal(start[:, t + 1], done[:, t])
        new_carry, _ = apply(params, (carry[0][:, t], carry[1][:, t]), obs[:, t])
        for stored, fresh in zip(carry, new_carry):
            expected = np.where(start[:, t + 1, None], 0.0, np.asarray(fresh))
            np.testing.assert_allclose(stored[:, t + 1], expected, rtol=1e-5, atol=1e-6)
        cont = ~start[:, t + 1]
        np.testing.assert_array_equal(data["next_obs"][cont, t], obs[cont, t + 1])


def test_load_policy_gives_a_pure_deterministic_policy():
    policy = load_policy(finished_run())
    assert isinstance(policy, Policy) and policy.name == "easy"
    act = jax.jit(policy.act)
    obs = jnp.linspace(-1, 1, 26)
    c1, a1 = act(policy.params, policy.init_carry(), obs, {}, jax.random.PRNGKey(0))
    _, a2 = act(policy.params, policy.init_carry(), obs, {}, jax.random.PRNGKey(1))
    np.testing.assert_array_equal(np.asarray(a1), np.asarray(a2))
    assert a1.shape == (3,) and np.all(np.abs(np.asarray(a1)) <= 1.0)
    _, a3 = act(policy.params, c1, obs, {}, jax.random.PRNGKey(0))  # the carry is memory
    assert not np.allclose(np.asarray(a1), np.asarray(a3))
    carries = jax.vmap(lambda _: policy.init_carry())(jnp.arange(5))
    _, batch = jax.vmap(policy.act, (None, 0, 0, None, 0))(policy.params, carries, jnp.tile(obs, (5, 1)), {},
                                                          jax.random.split(jax.random.PRNGKey(0), 5))
    np.testing.assert_allclose(np.asarray(batch), np.tile(np.asarray(a1), (5, 1)), rtol=1e-6)


def test_load_policy_errors(tmp_path):
    with pytest.raises(RunDirError, match="does not exist"):
        load_policy(tmp_path / "nope")
    with pytest.raises(RunDirError, match="has no config.yaml"):
        load_policy(tmp_path)
    shutil.copy(finished_run() / "config.yaml", tmp_path / "config.yaml")
    with pytest.raises(RunDirError, match="has no checkpoint"):
        load_policy(tmp_path)
    with pytest.raises(RunDirError, match=r"seed_index=1: the run has num_seeds=1"):
        load_policy(finished_run(), seed_index=1)
    bad = tmp_path / "bad_config"
    shutil.copytree(finished_run(), bad)
    (bad / "config.yaml").write_text((bad / "config.yaml").read_text().replace("algo: td3", "algo: ppo"))
    with pytest.raises(RunDirError, match="incompatible config.*valid choices"):
        load_policy(bad)
    corrupt = tmp_path / "corrupt"
    shutil.copytree(finished_run(), corrupt)
    for f in (corrupt / "checkpoints" / "16000" / "policy").rglob("*"):
        if f.is_file():
            f.write_bytes(b"not a checkpoint")
    with pytest.raises(RunDirError, match="checkpoint 16000 .* is corrupt"):
        load_policy(corrupt, which="final")   # the item corrupted above


def test_command_line_refuses_bad_input_before_compiling(tmp_path):
    assert cli.main(["--config", "no_such_config"]) == cli.EXIT_CONFIG
    assert cli.main(["--config", "td3_lstm", "--set", "agent.bogus=1"]) == cli.EXIT_CONFIG
    assert cli.main(["--run-dir", str(tmp_path), "--resume"]) == cli.EXIT_CONFIG
    assert cli.main(["--config", "td3_lstm", "--run-dir", str(finished_run()), "--resume"]) == cli.EXIT_CONFIG
    assert cli.main(["--config", "td3_lstm", "--run-dir", str(finished_run())]) == cli.EXIT_CONFIG
    out = subprocess.run([sys.executable, "-m", "docrl_jax.train", "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "--resume" in out.stdout and "--set" in out.stdout


def test_non_finite_loss_stops_and_keeps_the_last_good_checkpoint(capsys, monkeypatch):
    """A real NaN, not an injected marker: a healthy first chunk is checkpointed, then the run resumes
    from it with the critics' weights scaled by 1e30 as they are read back (the checkpoint on disk stays
    good), so the critic loss of the first update overflows. The run must stop with EXIT_NONFINITE, say
    where, write no poisoned checkpoint or metrics row, and keep the last good checkpoint. Poisoned
    weights rather than absurd learning rates: those are constants of the chunk program, so that run
    compiled a training program of its own (about 35 s of this suite on 2 cores); this one runs the
    programs every trainer test shares."""
    d = tmp_dir("nonfinite")
    config = easy_config(train__checkpoint_every=4000)
    assert train_run.run(config, d, show_progress=False, stop_after_chunks=1) == cli.EXIT_INTERRUPTED
    assert checkpoint.latest_step(d) == 4000
    read_back = checkpoint.restore_newest_intact

    def poisoned(*args, **kwargs):
        restored = read_back(*args, **kwargs)
        agent = restored.state.agent
        agent = agent.replace(critic=jax.tree.map(lambda w: w * 1e30, agent.critic))
        return dataclasses.replace(restored, state=restored.state.replace(agent=agent))

    monkeypatch.setattr(checkpoint, "restore_newest_intact", poisoned)
    status = train_run.run(config, d, resume=True, console=cli.make_console(), show_progress=False)
    assert status == cli.EXIT_NONFINITE
    assert re.search(r"non-finite loss at env step \d+ \(seed 0\)", capsys.readouterr().out)
    assert checkpoint.latest_step(d) == 4000
    assert [int(r["env_steps"]) for r in _rows(d)] == [0]
    good = load_policy(d)  # the kept policy is finite
    assert all(np.isfinite(np.asarray(x)).all() for x in jax.tree.leaves(good.params))


def test_load_policy_reads_a_checkpoint_written_on_a_gpu():
    """The committed H100 run (benchmarks/results/h100/runs/) was saved with a CUDA topology; it must
    load on this CPU and act."""
    from pathlib import Path
    run = Path(__file__).resolve().parents[2] / "benchmarks/results/h100/runs/h100_td3_lstm_4096_shaped"
    policy = load_policy(run)
    carry, action = policy.act(policy.params, policy.init_carry(), jnp.zeros(26), {}, jax.random.PRNGKey(0))
    assert action.shape == (3,) and np.all(np.abs(np.asarray(action)) <= 1.0)
