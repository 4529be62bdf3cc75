"""`train.video_every`: a GIF of one W-A trial in the run's TensorBoard at evaluations
(docrl_jax/train/tb_video.py), read back from the event file; a machine that cannot render warns
once and trains on. The runs are the trainer tests' easy config (its programs compile once)."""

from __future__ import annotations

import io
import struct

import numpy as np
import pytest
from _trainer_common import easy_config, finished_run, tmp_dir
from PIL import Image

from docrl_jax.config import ConfigError, load_config, packaged_configs_dir
from docrl_jax.errors import RenderError
from docrl_jax.train import cli, tb_video
from docrl_jax.train import run as train_run
from docrl_jax.console import make_console


def _events(run_dir):
    """Every Event of the run's TensorBoard files (TFRecord framing: length, its CRC, data, its CRC)."""
    from tensorboardX.proto.event_pb2 import Event
    events = []
    for path in sorted((run_dir / "tb").glob("events.out.tfevents.*")):
        data = path.read_bytes()
        at = 0
        while at < len(data):
            (n,) = struct.unpack("<Q", data[at:at + 8])
            events.append(Event.FromString(data[at + 12:at + 12 + n]))
            at += 12 + n + 4
    return events


def _images(run_dir, tag=tb_video.TAG):
    return [(e.step, v.image) for e in _events(run_dir) for v in e.summary.value if v.tag == tag]


def test_video_every_writes_a_gif_per_due_evaluation():
    # Evaluations at 0, 4,000, 8,000: the 1st, the 3rd (also the last). Half the easy run's length and
    # evaluation spacing (neither enters the compiled programs): the same three evaluations and two due
    # videos, from a policy that needs no more training to be drawn.
    d = finished_run(train__video_every=2, train__total_env_steps=8000, train__eval_every=4000)
    images = _images(d)
    assert [step for step, _ in images] == [0, 8000]
    for _, image in images:
        assert (image.height, image.width, image.colorspace) == (tb_video.HEIGHT, tb_video.WIDTH, 3)
        gif = Image.open(io.BytesIO(image.encoded_image_string))
        assert gif.format == "GIF" and gif.size == (tb_video.WIDTH, tb_video.HEIGHT)
        assert 2 <= gif.n_frames <= tb_video.MAX_FRAMES + 1
        gif.seek(gif.n_frames - 1)
        assert np.asarray(gif.convert("RGB")).std() > 10   # a picture
    # The scalars are still there (the video is a side effect beside them).
    assert any(v.tag == "eval/success_rate" for e in _events(d) for v in e.summary.value)


def test_a_machine_that_cannot_render_warns_once_and_trains_on(monkeypatch):
    import docrl_jax.envs.rendering as rendering

    def no_gl(*args, **kwargs):
        raise RenderError.no_gl("no display (test)")
    monkeypatch.setattr(rendering, "Renderer", no_gl)
    d = tmp_dir("video_no_gl")
    config = easy_config(train__video_every=1, train__total_env_steps=8000)   # 3 evaluations, all due
    log = io.StringIO()
    assert train_run.run(config, d, console=make_console(file=log, width=200), show_progress=False) == cli.EXIT_OK
    out = log.getvalue()
    assert out.count("no TensorBoard videos") == 1 and "MUJOCO_GL" in out, out
    assert "done: 8,000 env steps" in out and _images(d) == []


def test_video_every_is_off_in_every_packaged_config_and_checked():
    for path in sorted(packaged_configs_dir().glob("*.yaml")):
        assert load_config(path, backend="cpu").train.video_every == 0, path.name
    with pytest.raises(ConfigError, match="train.video_every"):
        easy_config(train__video_every=-1)


def test_video_due_every_nth_evaluation_and_the_last():
    v = tb_video.TrialVideo(easy_config(train__video_every=3), None, None, primary=True)
    assert [v.due(final=k == 7) for k in range(8)] == [True, False, False, True, False, False, True, True]
    off = tb_video.TrialVideo(easy_config(), None, None, primary=True)
    assert not any(off.due(final=True) for _ in range(3))
