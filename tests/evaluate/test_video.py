"""`python -m docrl_jax.render` (docrl_jax/evaluate/video.py): the evaluator's trials drawn, written as
MP4 and GIF, and the command's refusals.

The trials are the scripted oracle's in the empty tank on the evaluator tests' env (test_evaluate.py),
so the evaluator's own rollout they are compared with is the one those tests compile; the rendering
rollout compiles once for the module. The command itself runs once end to end on the trained
td3_lstm policy of tests/data."""

from __future__ import annotations

import sys
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from docrl_jax import evaluate
from docrl_jax.baselines.scripted import straight_line
from docrl_jax.envs.rendering import Renderer
from docrl_jax.evaluate import video

from _evaluator_world import LOW_FLOOR, MAX_STEPS, N   # the evaluator tests' env: their compiled rollout

TRAINED = str(Path(__file__).resolve().parents[1] / "data" / "trained" / "td3_lstm")
W, H = 128, 64   # both views, 64 x 64 each
FPS = 10.0


@pytest.fixture(scope="module")
def env():
    return evaluate.make_eval_env(1, MAX_STEPS, z_bounds=LOW_FLOOR)


@pytest.fixture(scope="module")
def drawn(env):
    """The first two of the evaluator's N trials per direction, with render records, and their frames."""
    out = {}
    with Renderer(env.mj_model, env.params, W, H) as r:
        for direction in ("air_to_water", "water_to_air"):
            trials = video.trials_to_render(env, straight_line(), 1, direction, 2, N, MAX_STEPS)
            tracks = video.tracks(trials, env.control_dt, "oracle {trial}/{trials}")
            frames, durations = video.render_frames(r, tracks, every=4, fps=FPS)
            out[direction] = trials, tracks, frames, durations
    return out


def test_the_trials_are_the_evaluators(drawn):
    trials = drawn["air_to_water"][0]
    kw = dict(scenarios=[1], directions=["air_to_water"], num_trials=N, max_steps=MAX_STEPS,
              env_overrides={"z_bounds": LOW_FLOOR})
    (_, evaluated), = evaluate.evaluate_policy(straight_line(), "oracle", seed=0, **kw)
    np.testing.assert_array_equal(trials["positions"], evaluated["positions"][:2])
    np.testing.assert_array_equal(trials["steps"], evaluated["steps"][:2])
    np.testing.assert_array_equal(trials["qpos"][..., :3], trials["positions"])   # the drawn pose is the trial's
    assert trials["success"].all()


def test_random_trials_come_from_the_reset_distribution(env, drawn):
    """N random trials run as one rollout (the module's compiled one: same N), one goal each."""
    a = video.trials_to_render(env, straight_line(), 1, "random", N, None, MAX_STEPS)
    b = video.trials_to_render(env, straight_line(), 1, "random", N, None, MAX_STEPS, seed=1)
    goals = a["goal"][:, 0]
    assert len({tuple(g) for g in np.round(goals, 4)}) == N and np.all(a["goal"] == goals[:, None])
    assert not np.allclose(a["start_positions"], b["start_positions"])   # the seed picks them
    np.testing.assert_array_equal(a["qpos"][:, 0, :3], a["start_positions"])
    assert np.all(np.abs(goals[:, :2]) < 4.9) and np.all(np.abs(a["start_positions"][:, :2]) < 4.9)
    np.testing.assert_array_equal(video.trials_to_render(env, straight_line(), 1, "random", N, None, MAX_STEPS)["qpos"],
                                  a["qpos"])


def test_frames_follow_the_trial(env, drawn):
    trials, tracks, frames, durations = drawn["air_to_water"]
    per_trial = [len(range(0, len(t), 4)) + ((len(t) - 1) % 4 != 0) for t in tracks]   # every 4th and the last
    assert [len(t) for t in tracks] == list(trials["steps"] + 1)
    assert frames.shape == (sum(per_trial), H, W, 3) and frames.dtype == np.uint8
    assert len(durations) == len(frames) and durations[per_trial[0] - 1] == pytest.approx(1 / FPS + video.HOLD_S)
    # The vehicle's pixels move in the overview (right half) while it flies 4 m: first vs last frame
    # of trial 1, where the vehicle is left out of the frame to find its pixels.
    with Renderer(env.mj_model, env.params, W, H, overlay=False, fan=False) as r:
        track = tracks[0]
        centres = []
        for t in (0, len(track) - 1):
            a = r.frame(track.qpos[t], track.goal[t]).astype(int)
            b = r.frame(track.qpos[t], track.goal[t], vehicle=False).astype(int)
            mask = np.abs(a - b).max(-1)[:, W // 2:] > 25
            assert mask.sum() > 3
            centres.append(np.argwhere(mask).mean(0))
    assert np.linalg.norm(centres[0] - centres[1]) > 8, centres
    # Consecutive frames differ (the scene moves with the vehicle), the overlay says the outcome.
    assert np.abs(frames[1].astype(int) - frames[0]).mean() > 1


def test_underwater_frames_are_tinted(drawn):
    """W-A starts 1 m under water, A-W 2.5 m above it: the follow camera's first view (left half)."""
    wet = drawn["water_to_air"][2][0, :, : W // 2].astype(float)
    dry = drawn["air_to_water"][2][0, :, : W // 2].astype(float)
    blue_green = lambda f: f[..., 1:].mean() - f[..., 0].mean()  # noqa: E731
    assert blue_green(wet) > blue_green(dry) + 20, (blue_green(wet), blue_green(dry))


@pytest.mark.filterwarnings("ignore:os.fork:RuntimeWarning")   # imageio-ffmpeg reads through a subprocess
@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_written_video_decodes(drawn, tmp_path, suffix):
    _, _, frames, durations = drawn["water_to_air"]
    path = tmp_path / f"v{suffix}"
    written = video.write_video(path, frames, durations, FPS)
    # A GIF keeps each frame once with its duration; an MP4 has a constant rate, so holds repeat frames.
    expected = len(frames) if suffix == ".gif" else sum(max(1, round(d * FPS)) for d in durations)
    assert written == expected
    decoded = iio.imread(path, index=None)
    assert decoded.shape == (expected, H, W, 3)
    # Lossy (MP4) or palette (GIF) coding keeps the picture: the first frame is close to what was drawn.
    assert np.abs(decoded[0].astype(int) - frames[0]).mean() < 12


def test_command_renders_a_trained_policy(tmp_path, capsys):
    out = tmp_path / "wa.gif"
    argv = ["--run", TRAINED, "--scenarios", "2", "--directions", "W-A", "--trials", "2", "--of", "3",
            "--max-steps", "12", "--width", "96", "--height", "48", "--every", "3", "--out", str(out)]
    assert video.main(argv) == 0
    text = capsys.readouterr().out
    assert "trial 1/2 of 3: timeout after 12 steps" in text and "trial 2/2 of 3" in text
    assert "td3_lstm (best): best policy of seed index 0" in text   # the run's policy, labelled as such
    assert f"wrote {out}: 10 frames of 96x48" in text   # 2 trials x (steps 0, 3, 6, 9, 12)
    assert iio.imread(out, index=None).shape == (10, 48, 96, 3)


@pytest.mark.parametrize("argv, message", [
    (["--run", "no/such/run", "--out", "x.gif"], "does not exist"),
    (["--policy", "ppo", "--out", "x.gif"], "valid choices: bba"),
    (["--policy", "bba", "--scenario", "4", "--out", "x.gif"], "--scenarios '4': valid scenarios are 1, 2, 3"),
    (["--policy", "bba", "--direction", "up", "--out", "x.gif"], "air_to_water (A-W), water_to_air (W-A), random"),
    (["--policy", "bba", "--out", "x.avi"], "valid suffixes are .mp4, .gif"),
    (["--policy", "bba", "--trials", "3", "--of", "2", "--out", "x.gif"], "--of 2: must be at least --trials 3"),
    (["--policy", "bba", "--direction", "random", "--of", "5", "--out", "x.gif"], "random trials"),
    (["--policy", "bba", "--width", "101", "--out", "x.gif"], "even number"),
    (["--policy", "bba", "--camera", "top", "--out", "x.gif"], "invalid choice: 'top'"),
    (["--policy", "bba", "--env", "wind=maybe", "--out", "x.gif"], "--env wind"),
    (["--run", TRAINED, "--seed-index", "3", "--out", "x.gif"], "valid 0..0"),
])
def test_bad_input_is_one_line_before_compiling(argv, message, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(video, "trials_to_render", lambda *a, **k: pytest.fail("compiled despite a bad input"))
    with pytest.raises(SystemExit) as exit_:
        video.main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1] and err[-1].startswith("python -m docrl_jax.render: error:"), err
    assert not list(tmp_path.iterdir())   # nothing written


def test_unwritable_out_and_missing_imageio(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(video, "trials_to_render", lambda *a, **k: pytest.fail("compiled despite a bad input"))
    not_a_folder = tmp_path / "file"
    not_a_folder.write_text("")
    with pytest.raises(SystemExit) as exit_:   # a path under a file: unwritable, even for root
        video.main(["--policy", "bba", "--out", str(not_a_folder / "x.gif")])
    assert exit_.value.code == 2 and "Not a directory" in capsys.readouterr().err
    monkeypatch.setitem(sys.modules, "imageio", None)
    with pytest.raises(SystemExit) as exit_:
        video.main(["--policy", "bba", "--out", str(tmp_path / "x.mp4")])
    assert exit_.value.code == 2 and "pip install -e '.[render]', or write a .gif" in capsys.readouterr().err
    with pytest.raises(ImportError, match=r"pip install -e '\.\[render\]'"):
        video.write_video(tmp_path / "y.mp4", np.zeros((1, 32, 32, 3), np.uint8), [0.1])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]
