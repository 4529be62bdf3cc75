"""MuJoCo's renderer for the env (docrl_jax/envs/rendering.py): `HUAUVEnv.render`, what the frames
show (the vehicle where its state says, the follow camera on it, a water tint under water), the
Gymnasium adapters' render_mode="rgb_array", and the one-line error of a machine without OpenGL.

The states come from the reference env the env contract and adapter tests compile
(`conftest.env_fns(1, wind=False)`), so nothing compiles here but the adapters' cheap programs."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.envs.rendering import Renderer, track_from_states

W, H = 160, 96   # both views: 80 x 96 each


@pytest.fixture(scope="module")
def states(env_fns):
    """Reset states in air at two places (same yaw, goal), one under water, and a short rollout."""
    env, reset_to, rollout = env_fns(1, wind=False)
    key, goal = jax.random.PRNGKey(0), jnp.array([0.0, 3.0, 2.0])
    west = reset_to(key, jnp.array([-2.5, -2.0, 2.0]), 0.0, goal)
    east = reset_to(key, jnp.array([2.5, -2.0, 2.0]), 0.0, goal)
    wet = reset_to(key, jnp.array([2.5, -2.0, -1.0]), 0.0, goal)
    moved, _ = rollout(west, jnp.tile(jnp.array([1.0, 0.0, 0.0]), (4, 1)))
    return env, {"west": west, "east": east, "wet": wet, "moved": moved}


def _vehicle_mask(renderer, state) -> np.ndarray:
    """Pixels that change when the vehicle is left out of the frame (overlay off)."""
    track = track_from_states([state])
    args = (track.qpos[0], track.goal[0], None, None)
    diff = np.abs(renderer.frame(*args).astype(int) - renderer.frame(*args, vehicle=False).astype(int))
    return diff.max(-1) > 25


def test_env_render_returns_uint8_frames_of_the_states(states, same_picture):
    env, s = states
    frames = env.render([s["west"], s["moved"], s["east"]], width=W, height=H)
    assert frames.shape == (3, H, W, 3) and frames.dtype == np.uint8
    assert frames.std() > 10   # a picture, not a blank
    # An EnvState stacked over time is the same as the list of its steps.
    stacked = jax.tree.map(lambda *xs: jnp.stack(xs), s["west"], s["moved"], s["east"])
    same_picture(env.render(stacked, width=W, height=H), frames)
    assert env.render([s["west"]], camera="overview", width=80, height=64, overlay=False).shape == (1, 64, 80, 3)
    with pytest.raises(ValueError, match="valid cameras are both, follow, overview"):
        env.render([s["west"]], camera="top")


def test_vehicle_drawn_where_its_state_is(states):
    env, s = states
    with Renderer(env.mj_model, env.params, 160, 120, camera="overview", fan=False, overlay=False) as r:
        west, east = _vehicle_mask(r, s["west"]), _vehicle_mask(r, s["east"])
    assert 5 < west.sum() < 0.2 * west.size and 5 < east.sum() < 0.2 * east.size
    # 5 m apart along x: the overview sees the vehicle's pixels far apart.
    cw, ce = np.argwhere(west).mean(0), np.argwhere(east).mean(0)
    assert np.linalg.norm(cw - ce) > 20, (cw, ce)
    with Renderer(env.mj_model, env.params, 160, 120, camera="follow", fan=False, overlay=False) as r:
        for name in ("west", "east"):   # the follow camera keeps the vehicle in the middle of its view
            rows, cols = np.nonzero(_vehicle_mask(r, s[name]))
            assert abs(cols.mean() - 80) < 16 and rows.size > 100, (name, cols.mean(), rows.size)


def test_underwater_views_are_tinted(states):
    env, s = states
    frames = env.render([s["east"], s["wet"]], camera="follow", width=W, height=H, overlay=False)
    blue_green = lambda f: float(f[..., 1:].mean() - f[..., 0].mean())  # noqa: E731
    assert blue_green(frames[1]) > blue_green(frames[0]) + 20, (blue_green(frames[0]), blue_green(frames[1]))


def test_gym_render_mode_rgb_array():
    import gymnasium

    from docrl_jax.envs.gym_env import ENV_ID, HUAUVVectorEnv
    # The adapter tests' settings: their compiled programs are reused.
    from _adapter_settings import GYM_KW, NUM_ENVS
    env = gymnasium.make(ENV_ID, render_mode="rgb_array", render_width=96, render_height=64, **GYM_KW)
    try:
        assert env.metadata["render_fps"] == 5 and "rgb_array" in env.metadata["render_modes"]
        env.reset(seed=3)
        first = env.render()
        for _ in range(3):
            env.step(np.array([1.0, 0.0, 0.5], np.float32))
        last = env.render()
        assert first.shape == last.shape == (64, 96, 3) and last.dtype == np.uint8
        assert np.abs(first.astype(int) - last).mean() > 1   # the vehicle moved and turned
    finally:
        env.close()
    venv = HUAUVVectorEnv(NUM_ENVS, render_mode="rgb_array", render_width=64, render_height=48, **GYM_KW)
    try:
        venv.reset(seed=1)
        frames = venv.render()
        assert len(frames) == NUM_ENVS and all(f.shape == (48, 64, 3) and f.dtype == np.uint8 for f in frames)
    finally:
        venv.close()
    with pytest.raises(ValueError, match="valid render modes are"):
        HUAUVVectorEnv(1, render_mode="human", **GYM_KW)


def test_gym_record_video(tmp_path):
    pytest.importorskip("moviepy")   # RecordVideo writes its files with moviepy
    import gymnasium
    from gymnasium.wrappers import RecordVideo

    from docrl_jax.envs.gym_env import ENV_ID
    from _adapter_settings import GYM_KW
    env = RecordVideo(gymnasium.make(ENV_ID, render_mode="rgb_array", render_width=64, render_height=48, **GYM_KW),
                      str(tmp_path), episode_trigger=lambda e: True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.zeros(3, np.float32))
        done = terminated or truncated
    env.close()
    assert list(tmp_path.glob("*.mp4"))


def test_no_gl_backend_is_one_line_and_imageio_stays_optional(tmp_path):
    """GLFW without a display cannot render: the command says so in one line naming MUJOCO_GL, and
    exits 2 before any rollout compiles; imageio (the [render] extra) is needed by MP4 only."""
    code = ("import sys; sys.modules['imageio'] = None\n"
            "import docrl_jax.envs, docrl_jax.envs.rendering, docrl_jax.train.tb_video\n"
            "from docrl_jax.evaluate import video\n"
            f"sys.exit(video.main(['--policy', 'bba', '--scenario', '1', '--out', {str(tmp_path / 'x.gif')!r}]))\n")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**env, "MUJOCO_GL": "glfw"})
    assert res.returncode == 2, res.stdout + res.stderr
    lines = [line for line in res.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), res.stderr
    assert "MUJOCO_GL=glfw" in lines[0] and "egl, osmesa, glfw" in lines[0]
    assert not (tmp_path / "x.gif").exists()


def test_vertical_beams_drawn_above_and_below_the_vehicle(states):
    """`vertical_ranges` (env.vertical_beams) add two beams along body +z and -z: in the follow view a
    line through the vehicle, above and below it; the plain env's states carry none."""
    env, s = states
    track = track_from_states([s["west"]])
    assert track.vertical_ranges.shape == (1, 0)
    args = (track.qpos[0], track.goal[0], track.ranges[0], False)
    with Renderer(env.mj_model, dataclasses.replace(env.params, vertical_beams=True), 160, 120, camera="follow",
                  overlay=False) as r:
        plain = r.frame(*args).astype(int)
        beams = np.abs(r.frame(*args, vertical_ranges=np.array([1.5, 1.5])).astype(int) - plain).max(-1) > 25
        with pytest.raises(ValueError, match="vertical_beams, slant_beams"):
            r.frame(*args, vertical_ranges=np.array([1.5, 1.5, 1.5]))
        vehicle = np.argwhere(_vehicle_mask(r, s["west"])).mean(0)
    rows, cols = np.nonzero(beams)
    assert rows.size > 10 and abs(cols.mean() - vehicle[1]) < 8, (rows.size, cols.mean(), vehicle)
    assert rows.min() < vehicle[0] - 10 and rows.max() > vehicle[0] + 10, (rows.min(), rows.max(), vehicle)


def test_the_renderer_and_what_it_draws_of_a_trajectory_are_two_modules_of_at_most_400_lines():
    """docrl_jax/envs/rendering.py draws; docrl_jax/envs/render_tracks.py holds the `Track` it draws
    and builds it. The renderer's names for the latter are the same objects, not copies."""
    from docrl_jax.envs import render_tracks, rendering
    for module in (rendering, render_tracks):
        with open(module.__file__) as f:
            assert len(f.readlines()) <= 400, module.__file__
    for name in render_tracks.__all__:
        if hasattr(rendering, name):
            assert getattr(rendering, name) is getattr(render_tracks, name), name
