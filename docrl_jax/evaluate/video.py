"""`python -m docrl_jax.render`: the evaluator's trials drawn by MuJoCo's renderer, as an MP4 or a GIF.

    python -m docrl_jax.render        # the shipped generalist's first scenario-2 W-A trial -> flight.gif
    python -m docrl_jax.render --run runs/d --scenarios 2 --directions water_to_air --out wa.mp4
    python -m docrl_jax.render --policy bba --scenarios 3 --directions air_to_water --trials 3 --out bba.gif
    python -m docrl_jax.render --run runs/d --directions water_to_air --trials 1 --of 100 --out first.gif
    python -m docrl_jax.render --run runs/d --directions random --trials 4 --camera follow --out random.mp4
    python -m docrl_jax.render --policy bba --tank gallery --directions air_to_water --trials 3 --out tanks.gif

The trials are the evaluator's (docrl_jax.evaluate.rollout and protocol: the same env settings, seeds
and rollout, which here also records the pose and the ranges of every step): `--trials K` draws the K
trials that `python -m docrl_jax.evaluate --trials K` runs for that scenario and direction, and
`--of N` the first K of the N trials of `evaluate --trials N`. `random`: starts and goals drawn from
the env's reset distribution, trial i from a key of (--seed, scenario, i). `--tank PATH|DIR|NAME`: the
trials of `python -m docrl_jax.evaluate --tank` (trial i in tank i mod the set's size; any tank file,
drawn in its own tank: docrl_jax.evaluate.tank_trials). A video flies one scenario and one direction:
`--scenarios` and `--directions` (the evaluator's flags; `--scenario`, `--direction` the same) take
one value. Trials are drawn one after
another, each ending on its outcome for a second. The frames are `envs.rendering.Renderer`'s (cameras,
water, goal, range fan, overlay). MP4 needs imageio and imageio-ffmpeg (`pip install -e '.[render]'`);
a GIF is written by Pillow, which the package always has. Bad input is one line and exit status 2,
before anything is compiled.

As a library: `trials_to_render` (the rollout), `tracks` (what is drawn of each trial), `render_frames`
and `write_video` / `encode_gif`; the trainer's TensorBoard videos (docrl_jax.train.tb_video) use them.
"""

from __future__ import annotations

import argparse
import io
import math
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from docrl_jax import flags, pretrained
from docrl_jax.arguments import UsageError, check_out
from docrl_jax.errors import RenderError, RunDirError, os_error_line, short_reason
from docrl_jax.evaluate.cli import check_guide
from docrl_jax.evaluate.tank_sets import TankSetError
from docrl_jax.evaluate.protocol import NOMINAL_YAW, OUTCOMES
from docrl_jax.evaluate.policies import policy_for
from docrl_jax.evaluate.tables import SHORT

SUFFIXES = (".mp4", ".gif")
RANDOM = "random"   # --directions random: starts and goals of the env's reset distribution
INSTALL = "pip install -e '.[render]'"
HOLD_S = 1.0        # each trial's last frame (its outcome) stays this long
RANDOM_SALT = 7     # random trials' keys: fold_in(fold_in(PRNGKey(seed), scenario), RANDOM_SALT + i)
# What the command draws without --run or --policy: a shipped policy's success (its first scenario-2
# W-A trial, 147 steps), a GIF of 2.5 MB at the default size.
DEFAULT_POLICY = "sac_mlp_generalist"
DEFAULT_OUT = "flight.gif"
GIF_EVERY = 2       # a GIF's default --every


def imageio_for(suffix: str):
    """imageio's v3 API for writing `suffix` (MP4 also needs imageio-ffmpeg, which brings its own ffmpeg);
    ImportError naming the extra when they are missing."""
    try:
        import imageio.v3 as iio
        if suffix == ".mp4":
            import imageio_ffmpeg  # noqa: F401  (imageio's ffmpeg plugin needs it and its ffmpeg binary)
    except ImportError as e:
        raise ImportError(f"writing {suffix} needs imageio and imageio-ffmpeg ({e.name or 'imageio'} is missing): "
                          f"{INSTALL}") from None
    return iio


# ------------------------------------------------------------------ trials
def trials_to_render(env, policy, scenario: int, direction: str, num_trials: int = 1, of: int | None = None,
                     max_steps: int = 500, seed: int = 0) -> dict[str, np.ndarray]:
    """The first `num_trials` of the evaluator's `of` (default `num_trials`) trials of one (scenario,
    direction), with the records the renderer needs (`rollout.run_trials(..., render=True)`); for
    `random`, trials from the env's reset distribution. Arrays with a leading trial axis."""
    import jax
    import docrl_jax.envs as envs
    from docrl_jax.evaluate import rollout
    if direction != RANDOM:
        start, goal = envs.eval_pair(scenario, direction)
        trials = rollout.run_trials(env, policy, start, goal, rollout.trial_key(seed, scenario, direction),
                                    of or num_trials, max_steps, NOMINAL_YAW[direction], render=True)
        return {k: (v[:num_trials] if np.ndim(v) else v) for k, v in trials.items()}
    base = jax.random.fold_in(jax.random.PRNGKey(seed), scenario)
    keys = jax.numpy.stack([jax.random.fold_in(base, RANDOM_SALT + i) for i in range(num_trials)])
    k_reset, k_trial = jax.vmap(jax.random.split, out_axes=1)(keys)
    return rollout.run_from_states(env, policy, rollout.reset_states(env, k_reset), k_trial, max_steps, render=True)


def outcome_line(trials: dict[str, np.ndarray], i: int, dt: float) -> str:
    """'success in 52 steps (10.4 s; air 4.2 s, water 6.2 s; path 6.1 m)' for trial i."""
    steps = int(trials["steps"][i])
    what = OUTCOMES[int(trials["outcome"][i])].replace("_", " ")
    line = f"{what} after {steps} steps ({steps * dt:.1f} s"
    if trials["success"][i]:
        line += f"; air {trials['t_air'][i]:.1f} s, water {trials['t_water'][i]:.1f} s; path {trials['path_length'][i]:.1f} m"
    return line + ")"


def tracks(trials: dict[str, np.ndarray], dt: float, title: str = "") -> list:
    """One `envs.rendering.Track` per trial, from its start to its last step; the last entry names
    the outcome. `title` may hold {trial} and {trials}."""
    from docrl_jax.envs.rendering import Track
    out = []
    n = len(trials["steps"])
    for i in range(n):
        end = int(trials["steps"][i]) + 1
        status = [""] * (end - 1) + [outcome_line(trials, i, dt)]
        out.append(Track(qpos=trials["qpos"][i, :end], goal=trials["goal"][i, :end], ranges=trials["ranges"][i, :end],
                         vertical_ranges=trials["vertical_ranges"][i, :end],
                         underwater=trials["underwater"][i, :end], step=np.arange(end),
                         distance=trials["distance"][i, :end], status=status,
                         title=title.format(trial=i + 1, trials=n)))
    return out


def render_frames(renderer, track_list: Sequence, every: int = 1, fps: float = 10.0,
                  hold_s: float = HOLD_S) -> tuple[np.ndarray, list[float]]:
    """Frames (F, H, W, 3) of the tracks one after another, and each frame's duration in seconds:
    1 / fps, and `hold_s` more on each track's last frame (its outcome)."""
    frames, durations = [], []
    for track in track_list:
        f = renderer.render_track(track, every=every)
        frames.append(f)
        durations += [1.0 / fps] * (len(f) - 1) + [1.0 / fps + hold_s]
    return np.concatenate(frames), durations


def encode_gif(frames: np.ndarray, durations: Sequence[float]) -> bytes:
    """An animated GIF (looping) of `frames`, by Pillow: one adaptive palette per frame."""
    from PIL import Image
    images = [Image.fromarray(f).quantize(colors=255, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
              for f in frames]
    ms = [max(20, int(round(d * 1000 / 10)) * 10) for d in durations]   # GIF delays are in 10 ms units
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=ms, loop=0,
                   disposal=1)
    return buf.getvalue()


def write_video(path: str | os.PathLike, frames: np.ndarray, durations: Sequence[float], fps: float = 10.0) -> int:
    """Writes `frames` to `path` (.mp4 through imageio-ffmpeg, H.264; .gif by Pillow); returns the
    number of frames in the file. An MP4 has a constant rate, so a longer duration repeats a frame."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".gif":
        path.write_bytes(encode_gif(frames, durations))
        return len(frames)
    if suffix != ".mp4":
        raise ValueError(f"{path}: unknown video suffix; valid suffixes are {', '.join(SUFFIXES)}")
    imageio_for(suffix)
    import imageio.v2 as imageio
    # imageio-ffmpeg starts ffmpeg with subprocess (fork + exec at once), which JAX's fork warning
    # is not about: it would be noise on every MP4.
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        return _write_mp4(imageio, path, frames, durations, fps)


def _write_mp4(imageio, path: Path, frames: np.ndarray, durations: Sequence[float], fps: float) -> int:
    written = 0
    with imageio.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7,
                            pixelformat="yuv420p", macro_block_size=1, ffmpeg_log_level="error") as writer:
        for frame, d in zip(frames, durations):
            for _ in range(max(1, int(round(d * fps)))):
                writer.append_data(frame)
                written += 1
    return written


# ------------------------------------------------------------------ the command
def build_parser() -> argparse.ArgumentParser:
    from docrl_jax.envs.render_tracks import CAMERAS
    from docrl_jax.arguments import OneLineParser, prog
    from docrl_jax.evaluate.cli import add_guide_argument, add_which_argument
    p = OneLineParser(prog=prog("render"), description=__doc__.split("\n\n")[0])
    src = p.add_mutually_exclusive_group()
    flags.add(src, "--run", ": its policy (--which)", metavar="RUN_DIR")
    flags.add(src, "--policy", f": {', '.join(pretrained.POLICY_NAMES)} (default without --run: {DEFAULT_POLICY}, "
                               "shipped in the package)", metavar="NAME")
    p.add_argument("--seed-index", type=int, default=0, help="which seed of --run (default 0)")
    add_which_argument(p)
    add_guide_argument(p)
    p.add_argument("--bba-depth-phase", default="after", help="BBA only: after (default), first, concurrent, in_air")
    flags.add(p, "--scenarios", "; a video flies one (default 2, the training scenario)", "--scenario", default=None)
    flags.add(p, "--tank", ", in place of a scenario: the trials of evaluate --tank (trial i in tank i mod the set's "
                           "size)", metavar="PATH|DIR|NAME")
    flags.add(p, "--directions", f", or {RANDOM} (starts and goals of the env's reset distribution); a video flies "
                                 "one (default water_to_air)", "--direction", default="water_to_air")
    flags.add(p, "--trials", ", drawn one after another (default 1)", default=1)
    p.add_argument("--of", type=int, default=None, metavar="N",
                   help="draw the first --trials of the evaluator's N trials (evaluate --trials N); default: of "
                        "--trials (paper directions only)")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of a trial (default 500, the paper's)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of the trials (default 0, the evaluator's)")
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help="env parameter override (repeatable), as for python -m docrl_jax.evaluate")
    p.add_argument("--camera", default="both", choices=CAMERAS,
                   help="follow (behind the vehicle), overview (the tank) or both side by side (default)")
    p.add_argument("--no-fan", action="store_true", help="leave the active range fan out")
    p.add_argument("--width", type=int, default=640, help="frame width in pixels, both views together (default 640)")
    p.add_argument("--height", type=int, default=240, help="frame height in pixels (default 240)")
    p.add_argument("--fps", type=float, default=10.0,
                   help="frames per second of the video (default 10; a control step is 0.2 s, so 5 is real time "
                        "with --every 1)")
    p.add_argument("--every", type=int, default=None, metavar="K",
                   help=f"draw every K-th control step (default {GIF_EVERY} for a GIF, whose frames are stored whole "
                        "(~36 KB each at 640x240), 1 for an MP4)")
    flags.add(p, "--out", f": the video, FILE.mp4 (H.264) or FILE.gif (default {DEFAULT_OUT})", default=DEFAULT_OUT,
              metavar="FILE")
    return p


def validate_args(args: argparse.Namespace) -> dict[str, Any]:
    """Checks the command line before anything is compiled; raises UsageError or RunDirError."""
    from docrl_jax.baselines.bba import DEPTH_PHASES
    from docrl_jax.evaluate import rollout
    from docrl_jax.evaluate.cli import parse_env_overrides
    from docrl_jax.evaluate.run_dirs import check_run_dir, run_vehicle
    if args.run is None:
        args.policy = pretrained.check_name((args.policy or DEFAULT_POLICY).lower())
    check_guide(args)
    if args.bba_depth_phase not in DEPTH_PHASES:
        raise UsageError(f"--bba-depth-phase {args.bba_depth_phase!r}: valid choices are {', '.join(DEPTH_PHASES)}")
    flags.check_tank_or_scenarios(args.tank, args.scenarios)
    scenario = 0 if args.tank is not None else flags.parse_scenarios(args.scenarios or "2", one="render")[0]
    direction = flags.parse_directions(args.directions, extra=(RANDOM,), one="render")[0]
    if args.tank is not None and direction == RANDOM:
        raise UsageError(f"--directions {RANDOM}: with --tank, give air_to_water (A-W) or water_to_air (W-A)")
    if args.every is None:
        args.every = GIF_EVERY if Path(args.out).suffix.lower() == ".gif" else 1
    for flag, value in (("--trials", args.trials), ("--max-steps", args.max_steps), ("--every", args.every)):
        flags.check_positive(flag, value)
    if args.of is not None:
        if direction == RANDOM or args.tank is not None:
            raise UsageError(f"--of: {'tank' if args.tank else RANDOM} trials do not depend on their number; "
                             "leave --of out")
        if args.of < args.trials:
            raise UsageError(f"--of {args.of}: must be at least --trials {args.trials}")
    if not args.fps > 0 or not math.isfinite(args.fps):
        raise UsageError(f"--fps {args.fps}: must be a positive number")
    for flag, value in (("--width", args.width), ("--height", args.height)):
        if value < 32 or value % 2:
            raise UsageError(f"{flag} {value}: must be an even number of pixels >= 32 (H.264 needs even sides)")
    if args.run is not None:
        check_run_dir(args.run)
        from docrl_jax import runs
        num_seeds = runs.read_config(args.run).train.num_seeds
        if not 0 <= args.seed_index < num_seeds:
            raise UsageError(f"--seed-index {args.seed_index}: the run has {num_seeds} seed(s) "
                             f"(valid 0..{num_seeds - 1})")
    out = Path(args.out)
    suffix = out.suffix.lower()
    if suffix not in SUFFIXES:
        raise UsageError(f"--out {args.out}: unknown video suffix {suffix or '(none)'!r}; valid suffixes are "
                         f"{', '.join(SUFFIXES)}")
    if suffix == ".mp4":   # a GIF is Pillow's
        try:
            imageio_for(suffix)
        except ImportError as e:
            raise UsageError(f"--out {args.out}: {e}, or write a .gif") from None
    env = parse_env_overrides(args.env, [scenario])
    env = rollout.flown_env(run_vehicle(args.run, args.policy), env)
    cfg = {"direction": direction, "env": env, "out": out, "scenario": scenario}
    if args.tank is not None:
        from docrl_jax.evaluate.tank_sets import check
        cfg["tank_names"] = check(args.tank, rollout.eval_params(0, args.max_steps, **env))
    check_out(out, folder=False)   # its missing folders are made when it is written
    check_memory(args, rollout.eval_params(scenario, args.max_steps, **env).observation_size)
    return cfg


def check_memory(args: argparse.Namespace, ranges: int) -> None:
    """--trials (and --of) against this machine's memory (trial_memory): each trial's records and, at
    most, a frame every --every steps, kept whole and once more joined (a GIF's palette images besides;
    --guide sensors draws the own map beside each)."""
    from docrl_jax.evaluate import trial_memory
    frames = -(-(args.max_steps + 1) // args.every)
    frame = args.width * args.height * (3 * 2 + 1) * (2 if args.guide == "sensors" else 1)
    start = args.tank is not None or args.guide is not None
    trial_memory.check("--trials", args.trials, trial_memory.Need(args.max_steps, from_states=start,
                                                                  render_ranges=ranges, frame_bytes=frames * frame))
    if args.of is not None:
        trial_memory.check("--of", args.of, trial_memory.Need(args.max_steps, from_states=start, render_ranges=ranges))


def import_mujoco() -> None:
    """Imports mujoco (MUJOCO_GL is read then); RenderError when MUJOCO_GL makes the import fail (a
    value MuJoCo does not know, or a backend whose library is missing)."""
    try:
        import mujoco  # noqa: F401
    except Exception as e:  # RuntimeError for an unknown value, AttributeError from PyOpenGL without libEGL
        raise RenderError.no_gl(f"import mujoco: {short_reason(e, 120)}") from None


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        import_mujoco()
    except RenderError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    try:
        cfg = validate_args(args)
    except (UsageError, RunDirError, pretrained.UnknownPolicy, TankSetError) as e:
        parser.error(str(e))   # one line, exit status 2
    try:
        return _render(args, cfg)
    except (RenderError, RunDirError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:
        print(f"error: {os_error_line(e)}", file=sys.stderr)
        return 2


def _render(args, cfg: dict) -> int:
    import contextlib

    import jax

    from docrl_jax.envs import layouts
    from docrl_jax.envs.rendering import Renderer
    from docrl_jax.evaluate import rollout, tank_sets, tank_trials
    t0 = time.time()
    scenario, direction = cfg["scenario"], cfg["direction"]
    env = rollout.make_eval_env(scenario, args.max_steps, **cfg["env"])
    # Each trial's scene: the scenario's, or its tank's (trial i in tank i mod the set's size).
    if args.tank is not None:
        names, tank_set = tank_sets.load(args.tank, env.params)
        scene = tank_sets.tank_index(args.trials, len(names))
        where = [f"tank {names[i]}" for i in scene]
        models = {i: layouts.mj_model(jax.tree.map(lambda x: np.asarray(x)[i], tank_set)) for i in set(scene)}
    else:
        scene, where, models = [0] * args.trials, [f"scenario {scenario}"] * args.trials, {0: env.mj_model}
    # The GL contexts first: a machine that cannot render says so before the rollout compiles.
    with contextlib.ExitStack() as contexts:
        renderers = {i: contexts.enter_context(Renderer(m, env.params, args.width, args.height, args.camera,
                                                        fan=not args.no_fan)) for i, m in models.items()}
        policy, label = policy_for(env, args.run, args.seed_index, args.which, args.bba_depth_phase, name=args.policy,
                                   guide=args.guide)
        if getattr(policy, "source", ""):
            print(f"{label}: {policy.source}", flush=True)
        if args.tank is not None:
            trials = tank_trials.run(policy, tank_set, direction, args.trials, args.max_steps, args.seed, cfg["env"],
                                     render=True)
        else:
            trials = trials_to_render(env, policy, scenario, direction, args.trials, args.of, args.max_steps,
                                      args.seed)
        name = SHORT.get(direction, direction)
        of = f" of {args.of}" if args.of else ""
        for i in range(args.trials):
            print(f"{where[i]} {name} {label} trial {i + 1}/{args.trials}{of}: "
                  f"{outcome_line(trials, i, env.control_dt)}", flush=True)
        t1 = time.time()
        parts = []
        for i, track in enumerate(tracks(trials, env.control_dt)):
            track.title = f"{label}  {where[i]} {name}  trial {i + 1}/{args.trials}{of}"
            frames, durations = render_frames(renderers[scene[i]], [track], args.every, args.fps)
            if args.guide == "sensors":   # what the vehicle knows, beside what it does
                from docrl_jax.envs import belief_view
                frames = belief_view.beside(frames, env.params, track, args.every)
            parts.append((frames, durations))
        frames, durations = np.concatenate([f for f, _ in parts]), [d for _, ds in parts for d in ds]
        t2 = time.time()
    cfg["out"].parent.mkdir(parents=True, exist_ok=True)
    written = write_video(cfg["out"], frames, durations, args.fps)
    views = 2 if args.camera == "both" else 1
    print(f"wrote {cfg['out']}: {written} frames of {args.width}x{args.height} at {args.fps:g} fps, "
          f"{cfg['out'].stat().st_size / 1e6:.2f} MB (rollout {t1 - t0:.1f} s, {len(frames)} frames drawn in "
          f"{t2 - t1:.1f} s: {len(frames) * views / max(t2 - t1, 1e-9):.1f} views/s)")
    return 0


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
