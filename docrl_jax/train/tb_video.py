"""`train.video_every`: a GIF of one water-to-air trial of the policy being trained, in the run's
TensorBoard, at evaluations.

The trial is trial 1 of `python -m docrl_jax.render --run RUN --direction water_to_air` in the run's
training scenario (the evaluator's env settings and seeds, docrl_jax.evaluate.video), acted by seed
index 0's policy (the actor's Polyak average, what checkpoints keep). It is drawn between compiled
chunks, on the host, by MuJoCo's renderer: a side effect outside jit. Every process takes part in
gathering the policy (a collective in a multi-process run), only process 0 draws and writes.

TensorBoard shows it under Images as `video/water_to_air`, one per evaluation step: an animated GIF
in an image summary (tensorboardX's own protos: its `add_video` needs moviepy), encoded by Pillow, at
most `MAX_FRAMES` frames of `WIDTH` x `HEIGHT` (a long trial is subsampled), so it stays a few
hundred kB. The first video compiles the trial's rollout (seconds) and opens the renderer; later ones
reuse both. A machine that cannot render (no OpenGL backend, MUJOCO_GL) or any error while drawing
prints one warning and the run goes on without videos.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Any, Callable

import jax

from docrl_jax.config import Config
from docrl_jax.errors import short_reason

TAG = "video/water_to_air"
DIRECTION = "water_to_air"
WIDTH, HEIGHT = 320, 120     # the follow and overview cameras side by side, 160 x 120 each
MAX_FRAMES = 60
FPS = 10.0
MAX_STEPS = 500              # the evaluator's step limit


class TrialVideo:
    """Decides when a video is due (`after_evaluation`), draws and writes it; `close()` at the end."""

    def __init__(self, config: Config, writer, console, primary: bool):
        self.config, self.writer, self.console, self.primary = config, writer, console, primary
        self.every = config.train.video_every
        self.evaluations = 0
        self.failed = False
        self._env = self._policy = self._renderer = None

    def due(self, final: bool) -> bool:
        """Whether the evaluation being done gets a video: every `video_every`-th of this launch (the
        first included) and the last. The same on every process (it counts evaluations only)."""
        k, self.evaluations = self.evaluations, self.evaluations + 1
        return self.every > 0 and (k % self.every == 0 or final)

    def after_evaluation(self, get_params: Callable[[], Any], env_steps: int, final: bool) -> None:
        """Called after each evaluation on every process; `get_params()` gives the actor parameters
        stacked over seeds (a collective: every process calls it when a video is due)."""
        if not self.due(final):
            return
        params = jax.tree.map(lambda x: x[0], get_params())
        if not self.primary or self.failed:
            return
        try:
            self._write(params, env_steps)
        except Exception as e:   # drawing must never end a run
            self.failed = True
            self.close()
            self.console.print(f"[yellow]warning:[/] no TensorBoard videos (train.video_every): {short_reason(e, 300)}; "
                               f"training goes on without them")

    def _write(self, params, env_steps: int) -> None:
        from docrl_jax import runs
        from docrl_jax.config import env_kwargs, pair_scenario
        from docrl_jax.envs.params import vehicle_overrides
        from docrl_jax.envs.rendering import Renderer
        from docrl_jax.evaluate import rollout, video
        t0 = time.time()
        scenario = pair_scenario(self.config)
        if self._env is None:
            self._env = rollout.make_eval_env(scenario, MAX_STEPS, **vehicle_overrides(env_kwargs(self.config)))
            self._renderer = Renderer(self._env.mj_model, self._env.params, WIDTH, HEIGHT, antialias=False)
            self._policy = runs.actor_policy(self.config, params)   # its functions: one compiled rollout
        policy = replace(self._policy, params=params)
        trials = video.trials_to_render(self._env, policy, scenario, DIRECTION, 1, None, MAX_STEPS)
        dt = self._env.control_dt
        every = max(1, math.ceil((int(trials["steps"][0]) + 1) / MAX_FRAMES))
        title = f"{self.config.name}  env step {env_steps:,}  scenario {scenario} W-A"
        frames, durations = video.render_frames(self._renderer, video.tracks(trials, dt, title), every, FPS)
        write_gif_summary(self.writer, TAG, video.encode_gif(frames, durations), frames.shape[1:3], env_steps)
        self.console.print(f"video at env step {env_steps:,}: W-A trial {video.outcome_line(trials, 0, dt)}; "
                           f"{len(frames)} frames in TensorBoard {TAG} ({time.time() - t0:.1f} s)")

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def write_gif_summary(writer, tag: str, gif: bytes, height_width: tuple[int, int], step: int) -> None:
    """An encoded GIF as a TensorBoard image summary at `step`, through tensorboardX's own protos and
    file writer (what its add_image and add_video do, without their PNG or moviepy encoding)."""
    from tensorboardX.proto.summary_pb2 import Summary
    height, width = height_width
    image = Summary.Image(height=int(height), width=int(width), colorspace=3, encoded_image_string=gif)
    writer._get_file_writer().add_summary(Summary(value=[Summary.Value(tag=tag, image=image)]), step)
