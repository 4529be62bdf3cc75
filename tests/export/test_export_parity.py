"""The exported artefacts act as the JAX policy does on the environment: 1,000 steps of the evaluator's
scenario-2 env driven by the JAX policy (the paper's pairs, A-W and W-A in turn, from the evaluator's
jittered starts; an episode ends at arrival, a collision or 500 steps, the carry zeroed at each
start), then the same observations fed to the ONNX, StableHLO and NumPy artefacts step by step, each
carrying its own carry: every action within 1e-5 of the JAX policy's, for the shipped td3_lstm and
sac_lstm policies and an untrained MLP actor. The same episodes show that Table I's shipped policies
fly (docrl_jax/pretrained; the generalist, in its own vehicle, in tests/test_pretrained.py) and the
untrained actor does not. Also: the observation as DEPLOY.md and examples/deploy_node.py build it
from the sensors and the pose is the env's own, and the example's 5 Hz node flies the exported policy."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax import pretrained
from docrl_jax.algorithms import make_agent
from docrl_jax.config import load_config
from docrl_jax.evaluate import rollout
from docrl_jax.evaluate.protocol import DIRECTIONS, NOMINAL_YAW, trial_starts
from docrl_jax.export import FORMATS, export_actor, export_shipped
from docrl_jax.export import cli as export_cli
from docrl_jax.export.runners import open_artefact
from docrl_jax.policy import Policy

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "deploy_node.py"
STEPS = 1000
TOLERANCE = 1e-5
INFO_KEYS = ("ranges", "underwater", "position", "yaw", "goal")


@pytest.fixture(scope="module")
def env_step():
    """The evaluator's scenario-2 env (wind; no range noise, so the info's ranges are the observation's)."""
    env = rollout.make_eval_env(2, 500, sensor_noise_std=0.0)
    return jax.jit(env.reset_to), jax.jit(env.step)


def _fresh_mlp_policy() -> tuple[Policy, object]:
    """A freshly initialised ddpg_mlp actor, as load_policy would give it (zero placeholder carry)."""
    config = load_config("ddpg_mlp", backend="cpu")
    agent = make_agent(config)
    params = jax.jit(agent.actor.init)(jax.random.PRNGKey(3), agent.actor.init_carry(()), jnp.zeros(26))

    def act(params, carry, obs, info, key):
        return agent.act(params, agent.actor.init_carry(()), obs)
    return Policy("ddpg_mlp", params, lambda: agent.actor.init_carry(()), act), config


def _rollout(env_step, policy: Policy, steps: int = STEPS, seed: int = 0) -> dict[str, np.ndarray]:
    """The JAX policy acting on the env: observations, its actions, episode-start flags and the info
    the observation was made from; `arrived`, one flag per episode ended (a trial of the protocol:
    episode i flies DIRECTIONS[i % 2] from its i-th jittered start)."""
    reset_to, step = env_step
    act = jax.jit(policy.act)
    key = jax.random.PRNGKey(seed)
    starts = {d: trial_starts(jax.random.fold_in(key, i), envs.eval_pair(2, d)[0], steps, NOMINAL_YAW[d])
              for i, d in enumerate(DIRECTIONS)}

    def reset(episode: int):
        direction = DIRECTIONS[episode % 2]
        position, yaw = (x[episode // 2] for x in starts[direction])
        return reset_to(jax.random.fold_in(key, 2 + episode), position, yaw, jnp.asarray(envs.eval_pair(2, direction)[1]))

    episode, state, start = 0, reset(0), True
    out = {name: [] for name in ("obs", "action", "start", "arrived", *INFO_KEYS)}
    for _ in range(steps):
        if start:
            carry = policy.init_carry()
        carry, action = act(policy.params, carry, state.obs, state.info, None)
        out["obs"].append(state.obs), out["action"].append(action), out["start"].append(start)
        for name in INFO_KEYS:
            out[name].append(state.info[name])
        state = step(state, action)
        start = bool(state.done)
        if start:
            out["arrived"].append(bool(state.info["arrived"]))
            episode += 1
            state = reset(episode)
    return {name: np.asarray(values) for name, values in out.items()}


def _replay(export_dir: Path, fmt: str, rollout: dict) -> np.ndarray:
    """The artefact's actions on the rollout's observations, its carry zeroed at each episode start."""
    runner = open_artefact(export_dir, fmt)
    actions = []
    for obs, start in zip(rollout["obs"], rollout["start"]):
        if start:
            carry = runner.initial_carry()
        action, carry = runner.step(obs[None], carry)
        actions.append(action[0])
    return np.asarray(actions)


@pytest.fixture(scope="module")
def exports(env_step, tmp_path_factory):
    """(rollout, export dir) per policy: the shipped td3_lstm through the command, the shipped sac_lstm
    through export_shipped, the fresh MLP through export_actor; the shipped sac_mlp flown, not exported."""
    root = tmp_path_factory.mktemp("exports")
    out = {}
    assert export_cli.main(["--policy", "td3_lstm", "--out", str(root / "td3_lstm")]) == 0
    out["td3_lstm"] = (_rollout(env_step, pretrained.load("td3_lstm"), seed=0), root / "td3_lstm")
    export_shipped("sac_lstm", root / "sac_lstm")
    out["sac_lstm"] = (_rollout(env_step, pretrained.load("sac_lstm"), seed=1), root / "sac_lstm")
    mlp, config = _fresh_mlp_policy()
    export_actor(config, mlp.params, root / "ddpg_mlp", source={"fresh": "ddpg_mlp, PRNGKey(3)"})
    out["ddpg_mlp"] = (_rollout(env_step, mlp, seed=2), root / "ddpg_mlp")
    out["sac_mlp"] = (_rollout(env_step, pretrained.load("sac_mlp"), seed=3), None)
    return out


@pytest.mark.parametrize("name", ["td3_lstm", "sac_lstm", "ddpg_mlp"])
def test_every_artefact_matches_the_jax_policy_at_every_step(exports, name):
    rollout, export_dir = exports[name]
    starts = int(rollout["start"].sum())
    assert starts >= 2, "the rollout must cross an episode start (the carry reset)"
    for fmt in FORMATS:
        actions = _replay(export_dir, fmt, rollout)
        worst = np.abs(actions - rollout["action"]).max(axis=-1)
        assert worst.max() <= TOLERANCE, (f"{name} {fmt}: step {int(worst.argmax())} differs by {worst.max():.2e} "
                                          f"from the JAX policy")


def test_the_trained_rollouts_see_both_media(exports):
    """The parity above covers the LIDAR (air) and the sonar (underwater) observations."""
    for name in ("td3_lstm", "sac_lstm"):
        underwater = exports[name][0]["underwater"]
        assert underwater.any() and not underwater.all(), name


def test_the_shipped_table_i_policies_fly_and_an_untrained_actor_does_not(exports):
    """Arrivals among the episodes ended: scenario 2 of docrl_jax/pretrained/README.md (of 100, A-W / W-A)
    is 100 / 97, 99 / 90 and 100 / 91; at least 80 % passes those and fails BBA's 34 / 0 (measured here:
    9 of 9, 9 of 9, 9 of 10; the untrained MLP 0 of 4)."""
    arrived = {name: exports[name][0]["arrived"] for name in ("td3_lstm", "sac_lstm", "sac_mlp", "ddpg_mlp")}
    for name in ("td3_lstm", "sac_lstm", "sac_mlp"):
        assert len(arrived[name]) >= 6 and arrived[name].mean() >= 0.8, (name, arrived[name])
    assert len(arrived["ddpg_mlp"]) >= 2 and not arrived["ddpg_mlp"].any(), arrived["ddpg_mlp"]   # untrained


def _example_module():
    spec = importlib.util.spec_from_file_location("deploy_node", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_documented_observation_is_the_envs(exports):
    """examples/deploy_node.py builds the observation from ranges, medium, previous action, position,
    yaw and goal as DEPLOY.md describes; it is the env's observation at every step."""
    rollout, export_dir = exports["td3_lstm"]
    manifest = open_artefact(export_dir, "numpy").manifest
    build = _example_module().build_observation
    previous = np.zeros(3, np.float32)
    for t in range(STEPS):
        if rollout["start"][t]:
            previous = np.zeros(3, np.float32)
        obs = build(manifest, rollout["ranges"][t], bool(rollout["underwater"][t]), previous,
                    rollout["position"][t], float(rollout["yaw"][t]), rollout["goal"][t])
        np.testing.assert_allclose(obs, rollout["obs"][t], atol=2e-6, rtol=0, err_msg=f"step {t}")
        previous = np.clip(rollout["action"][t], -1.0, 1.0)


@pytest.fixture
def isolated_imports(monkeypatch):
    """The example and DEPLOY.md import numpy_policy from an export directory put on sys.path."""
    monkeypatch.setattr(sys, "path", list(sys.path))
    yield
    sys.modules.pop("numpy_policy", None)


@pytest.mark.parametrize("fmt", FORMATS)
def test_the_example_node_flies_the_exported_policy(exports, fmt, isolated_imports):
    """The timer-callback loop of examples/deploy_node.py: the trained td3_lstm export reaches the
    goal of the air-to-water pair and of the water-to-air pair after it (a carry reset between)."""
    node = _example_module().PolicyNode(exports["td3_lstm"][1], fmt)
    for _ in range(200):
        node.on_timer()
    assert [(episode, end) for episode, end, _ in node.log[:2]] == [(0, "arrived"), (1, "arrived")], node.log


def test_the_example_runs_without_jax_or_docrl_jax(exports):
    """With the NumPy artefact the example needs numpy alone: jax, flax and docrl_jax cannot be imported."""
    blocked = "import sys; sys.modules.update(dict.fromkeys(['jax', 'jaxlib', 'flax', 'docrl_jax']));"
    argv = ["deploy_node.py", "--export", str(exports["td3_lstm"][1]), "--steps", "100"]
    run = f"import runpy; sys.argv = {argv!r}; runpy.run_path({str(EXAMPLE)!r}, run_name='__main__')"
    proc = subprocess.run([sys.executable, "-c", blocked + run], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "episode 0 (A-W): arrived" in proc.stdout and "100 callbacks with the numpy artefact" in proc.stdout


def test_the_python_blocks_of_deploy_md_run(exports, tmp_path, monkeypatch, isolated_imports):
    """docs/DEPLOY.md's ONNX, StableHLO and NumPy snippets, run as written against export/td3_lstm,
    give the same action."""
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "docs" / "DEPLOY.md").read_text(), re.S)
    assert len(blocks) == 3
    shutil.copytree(exports["td3_lstm"][1], tmp_path / "export" / "td3_lstm")
    monkeypatch.chdir(tmp_path)
    actions = []
    for block in blocks:
        namespace: dict = {}
        exec(compile(block, "docs/DEPLOY.md", "exec"), namespace)
        actions.append(np.asarray(namespace["action"]))
    assert actions[0].shape == (1, 3)
    for action in actions[1:]:
        np.testing.assert_allclose(action, actions[0], atol=1e-5, rtol=0)


def test_a_vertical_beam_policy_exports_and_the_example_builds_its_observation(env_fns, tmp_path):
    """A policy trained with env.vertical_beams takes 28 floats: its export is checked on 28-float
    observations, policy.json names floats 26-27, and examples/deploy_node.py, given the fan's ranges then
    up and down, builds the env's observation (the paper's 20 ranges alone are refused)."""
    config = load_config("td3_lstm_generalist", ["env.slant_beams=0"], backend="cpu")
    params = make_agent(config).init(jax.random.PRNGKey(5)).actor
    manifest = export_actor(config, params, tmp_path / "vertical", source={"fresh": "td3_lstm_generalist"},
                            formats=["numpy"])
    assert manifest["observation"]["size"] == 28 and manifest["observation"]["layout"][-1]["index"] == [26, 27]
    assert manifest["check"]["max_abs_action_diff"]["numpy"] < TOLERANCE
    _, reset_to, _ = env_fns(1, wind=False, vertical_beams=True)
    build = _example_module().build_observation
    for position, yaw, goal in (((1.0, -2.0, 2.0), 0.3, (0.0, 3.0, -1.0)), ((-2.0, 1.5, -0.6), -2.0, (2.0, 2.0, 2.5))):
        s = reset_to(jax.random.PRNGKey(0), jnp.array(position), yaw, jnp.array(goal))
        # Empty tank: nothing above the vehicle (the maximum range), the floor top 1.3 m under the surface.
        ranges = np.append(np.asarray(s.info["ranges"]), [20.0 if position[2] < 0 else 10.0, position[2] + 1.3])
        obs = build(manifest, ranges, position[2] < 0, np.zeros(3), position, yaw, goal)
        np.testing.assert_allclose(obs, np.asarray(s.obs), atol=2e-6, rtol=0)
    with pytest.raises(ValueError, match="20 ranges given; this policy takes 22"):
        build(manifest, ranges[:20], position[2] < 0, np.zeros(3), position, yaw, goal)


def test_slanted_beams_in_the_manifest_and_the_example():
    """env.slant_beams=3 at 40 degrees after the vertical beams: policy.json places the two rings at
    floats 28-33 with their geometry, and the example's observation builder takes 20 + 2 + 6 ranges
    and puts the extra 8 after the goal floats, scaled by the active sensor's maximum."""
    from docrl_jax.export.manifest import observation_spec
    config = load_config("td3_lstm_generalist", ["env.slant_beams=3", "env.slant_elevation_deg=40"], backend="cpu")
    spec = observation_spec(config)
    slanted = spec["layout"][-1]
    assert spec["size"] == 34 and slanted["name"] == "slanted_ranges" and slanted["index"] == [28, 33]
    assert "rings of 3 beams" in slanted["value"] and "40 degrees" in slanted["value"]
    assert spec["layout"][-2]["index"] == [26, 27]
    build = _example_module().build_observation
    ranges = np.arange(1.0, 29.0) / 10.0
    obs = build({"observation": spec}, ranges, False, np.zeros(3), (0.0, 0.0, 1.0), 0.0, (1.0, 0.0, 1.0))
    assert obs.shape == (34,)
    np.testing.assert_allclose(obs[26:], ranges[20:] / 10.0, rtol=1e-6)
    with pytest.raises(ValueError, match="22 ranges given; this policy takes 28"):
        build({"observation": spec}, ranges[:22], False, np.zeros(3), (0.0, 0.0, 1.0), 0.0, (1.0, 0.0, 1.0))
