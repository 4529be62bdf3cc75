"""One training run into its run directory, new or resumed: the body of `python -m docrl_jax.train`
(docrl_jax.train.cli reads the command line and calls `run`). The run directory holds config.yaml,
metrics.csv, TensorBoard logs, startup.json and the checkpoints (docrl_jax.runs reads them back).

    from docrl_jax.train.run import run
    run(config, "runs/mine")                       # trains; returns an exit code (docrl_jax.train.loop)
    run(config, "runs/mine", resume=True)          # continues from the newest intact checkpoint
"""

from __future__ import annotations

import contextlib
import json
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import jax
import mujoco
import numpy as np
from rich.console import Console, Group
from rich.live import Live
from rich.progress import BarColumn, Progress, TextColumn
from rich.text import Text

from docrl_jax import checkpoint, memory, runs, sharding
from docrl_jax.config import Config, differences, env_kwargs, to_yaml
from docrl_jax.envs import make_params
from docrl_jax.envs.huauv import scene_path
from docrl_jax.errors import ConfigError, RunDirError, os_error_line
from docrl_jax.train import best_policy, metrics, tb_video
from docrl_jax.console import EXIT_CONFIG, EXIT_INTERRUPTED, EXIT_OK, make_console
from docrl_jax.train.chunks import schedule
from docrl_jax.train.loop import Cadence, Evaluations, Hooks, Interrupt, run_chunks
from docrl_jax.train.programs import building_note, chunk_building, compile_programs, still_compiling_line

__all__ = ["check_resume_changes", "check_run_dir", "run"]


# What a resume may change of the run's config (--set): its length, where it runs, and how often it
# evaluates, checkpoints and records, none of which is in the checkpoints or changes what was trained.
# Every other key is the run's recipe or sets the shape of what its checkpoints hold.
RESUMABLE = ("name", "train.total_env_steps", "train.devices", "train.eval_every", "train.eval_every_minutes",
             "train.checkpoint_every", "train.checkpoint_every_minutes", "train.keep_checkpoints",
             "train.video_every")


def check_run_dir(run_dir: Path, resume: bool, config: Config | None = None) -> None:
    """Refuses what would lose or mix up a run: a new run into a directory that holds one (or a
    sweep), a resume of a sweep, of a directory without a run, or of a run with no checkpoint, and a
    resume whose `config` differs from the run's own but in RESUMABLE keys (before anything compiles
    and before the run's config.yaml is written over)."""
    if not resume:
        runs.check_fresh(run_dir)
        return
    if (run_dir / runs.SWEEP_FILE).is_file():
        raise RunDirError(f"{str(run_dir)!r} is a sweep: sweeps write no checkpoints and cannot be resumed; "
                          f"train one combination with --config {run_dir}/cNN/config.yaml")
    own = runs.read_config(run_dir)  # clear errors for a missing dir or config
    if checkpoint.latest_step(run_dir) is None:
        raise RunDirError(f"{str(run_dir)!r} has no checkpoint to resume from (the run stopped before its "
                          f"first); start it again with --config and a fresh --run-dir")
    if config is not None:
        check_resume_changes(run_dir, config, own)


def check_resume_changes(run_dir: Path, config: Config, own: Config | None = None) -> None:
    """Refuses a resume whose `config` differs from the run's own (`own`, else read from `run_dir`) but in
    RESUMABLE keys: one line naming each key and what a resume may change."""
    own = runs.read_config(run_dir) if own is None else own
    changed = [f"{key} ({was!r} -> {now!r})" for key, (was, now) in differences(own, config).items()
               if key not in RESUMABLE]
    if changed:
        may = ", ".join(key for key in RESUMABLE if key != "name")
        raise ConfigError(f"a resume continues the run as it was trained and cannot change {', '.join(changed)}; "
                          f"it may change {may}. To train otherwise, start a new run: "
                          f"--config {run_dir / runs.CONFIG_FILE} --set ...")


class _Display:
    """The progress bar with the latest statistics on a line of their own (they do not fit beside it),
    or with --no-progress, or when the output is not an interactive terminal (a log file, a pipe, a
    batch job), one whole printed line per chunk: a live display there is drawn once, at its end, cut
    at 80 columns, with the next message run onto its last line."""

    def __init__(self, console: Console, name: str, total: int, done: int, show_progress: bool):
        self.console, self.show_progress = console, show_progress and console.is_interactive
        self.progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                                 TextColumn("{task.completed:,.0f}/{task.total:,.0f} env steps"),
                                 TextColumn("{task.fields[sps]}"), TextColumn("{task.fields[eta]}"), console=console)
        self.task = self.progress.add_task(name, total=total, completed=done, sps="", eta="ETA once learning starts")
        self.line = "waiting for the first chunk"

    def __rich__(self):
        return Group(self.progress.get_renderable(), Text(self.line))

    def live(self):
        return Live(self, console=self.console, refresh_per_second=4) if self.show_progress else contextlib.nullcontext()

    def chunk(self, steps: int, sps: float, eta: str, line: str) -> None:
        self.progress.update(self.task, completed=steps, sps=f"{sps:,.0f} steps/s", eta=eta)
        self.line = line
        if not self.show_progress:
            self.console.print(f"{steps:,} steps  {sps:,.0f} steps/s  {eta}  {line}")


def _older_layouts(config: Config) -> tuple[checkpoint.OlderLayout, ...]:
    """The layouts of the run states earlier versions checkpointed, newest first. Before the scenes
    factored the mass matrix sparse (assets/common.xml), MJX kept it and its factor as dense nv x nv
    matrices and no inverse diagonal; every env step computes all three before it reads them. Before
    the own map, the env's info held no attitude ("rot"). Before the sparse mass matrix,
    SimState.training_margins did not exist either: on in every env exactly when the config has a
    training-only margin (those versions turned the evaluation lanes off then, so no lane needs it off)."""
    p = make_params(config.env.scenario, **env_kwargs(config))
    on = p.collision_margin > 0.0 or p.hull_margin > 0.0
    nv = mujoco.MjModel.from_xml_path(scene_path(p.scenario)).nv
    dense = (("M", lambda shape: (*shape[:-1], nv, nv)), ("qLD", lambda shape: (*shape[:-1], nv, nv)),
             ("qLDiagInv", lambda shape: (*shape[:-1], 0)))
    def fill(leaf):   # the margins as those versions set them; the info's attitude ("rot") is written by the
        #               next env step before anything reads it
        return np.full(leaf.shape, on, bool) if leaf.dtype == bool else np.zeros(leaf.shape, leaf.dtype)

    return (checkpoint.OlderLayout("the body's attitude in the env's info", ("rot",), fill),
            checkpoint.OlderLayout("the sparse mass matrix", ("rot",), fill, reshaped=dense),
            checkpoint.OlderLayout("the sparse mass matrix and SimState.training_margins", ("training_margins", "rot"),
                                   fill, reshaped=dense))


def _resume(mngr, state_shape, placement, config: Config, plan, metrics_path: Path, console: Console, primary: bool):
    """The newest intact checkpoint's runner state and bookkeeping; damaged newer checkpoints are
    named, skipped and set aside. Returns (state, chunks done, wall seconds before, pending
    statistics, best policies or None, the metrics.csv rows of the last evaluation kept)."""
    t_cfg = config.train
    restored = checkpoint.restore_newest_intact(
        mngr, state_shape, placement.seed_sharding,
        best_shape=state_shape.agent.actor_average if t_cfg.track_best_policy else None, older=_older_layouts(config))
    if restored.older:
        console.print(f"checkpoint {restored.step} predates {restored.older.what}: resumed with the run's state "
                      "read as that version wrote it")
    for step, reason in restored.skipped:
        console.print(f"[yellow]skipped checkpoint {step}:[/] {reason}")
    if restored.skipped:  # out of the way of the steps the resumed run writes again; nothing deleted
        if primary:
            aside = checkpoint.set_aside(mngr, [step for step, _ in restored.skipped])
            console.print(f"moved the skipped checkpoint(s) to {aside}")
        sharding.barrier()
        mngr.reload()
    step, state, meta = restored.step, restored.state, restored.meta
    done_chunks = meta["chunk"]
    if done_chunks * plan.steps_per_chunk != meta["env_steps"]:
        raise RunDirError(f"checkpoint {step} was written with another chunk size; train.log_every and "
                          f"env.num_envs cannot change on resume")
    # A checkpoint from before best-policy tracking starts it afresh at the next evaluation.
    best = best_policy.from_meta(placement.get(restored.best), meta["best"]) if restored.best is not None else None
    # A resume may lengthen the run (--set train.total_env_steps=...); schedules follow the new total.
    state = state.replace(total_steps=placement.put_seeds(
        np.full(state.total_steps.shape, plan.total_env_steps, np.int32)))
    last_rows = metrics.truncate_metrics(metrics_path, step) if primary else []
    console.print(f"resumed from env step {step:,} (chunk {done_chunks}/{plan.num_chunks})")
    return state, done_chunks, meta["wall_time_s"], meta["pending"], best, last_rows


class _NoWriter:
    """TensorBoard writer of the processes other than 0."""

    def add_scalar(self, *args, **kwargs):
        pass

    def close(self):
        pass


def run(config: Config, run_dir: str | Path, resume: bool = False, console: Console | None = None,
        show_progress: bool = True, launch_time: float | None = None, stop_after_chunks: int | None = None) -> int:
    """Trains (or resumes) `config` into `run_dir`; returns an exit code. A file-system error (a
    read-only directory, a full disk) ends it with one line naming the path and the cause; the
    checkpoints already written stay. `stop_after_chunks` acts like a Ctrl-C after that many
    chunks of this call (tests use it to interrupt a run)."""
    launch_time = time.time() if launch_time is None else launch_time
    # Several processes (docrl_jax.sharding) run this same loop in step; only process 0 writes files.
    primary = sharding.is_primary()
    console = console if console is not None and primary else make_console(quiet=not (show_progress and primary))
    try:
        return _run(config, Path(run_dir), resume, console, show_progress, launch_time, stop_after_chunks, primary)
    except (ConfigError, RunDirError) as e:
        console.print(f"[bold red]error:[/] {e}")
        return EXIT_CONFIG
    except OSError as e:
        console.print(f"[bold red]error:[/] {os_error_line(e)}")
        return EXIT_CONFIG
    except KeyboardInterrupt:
        newest = checkpoint.latest_step(run_dir)
        console.print(f"quit without saving; newest checkpoint: "
                      f"{'none' if newest is None else f'env step {newest:,}'} in {Path(run_dir) / checkpoint.CHECKPOINT_DIR}")
        return EXIT_INTERRUPTED


def _run(config: Config, run_dir: Path, resume: bool, console: Console, show_progress: bool, launch_time: float,
         stop_after_chunks: int | None, primary: bool) -> int:
    # startup.json: seconds after launch at each step of the start (the command line's imports and
    # config before `run`), and whether the programs were compiled or loaded
    startup = {"launch_to_run_s": round(time.time() - launch_time, 2)}
    # The command line checked the directory before its imports; a caller from Python gets the same check
    # here, before anything is written (a new run would overwrite a run's config and metrics).
    check_run_dir(run_dir, resume, config)
    t_cfg = config.train
    placement = sharding.seed_placement(t_cfg)  # the device plan, resolved once for the whole run
    memory.check_memory(config, placement.devices)
    sharding.barrier()  # every process has read the run directory before process 0 writes to it
    if placement.note:
        console.print(f"[yellow]note:[/] {placement.note}")
    if primary:
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / runs.CONFIG_FILE).write_text(to_yaml(config))
    plan = schedule(config)
    seeds = [t_cfg.seed + i for i in range(t_cfg.num_seeds)]
    keys = placement.seed_keys(seeds)
    console.print("compiling (or loading) the training, evaluation and initialisation programs ...")
    pool = ThreadPoolExecutor(1)  # TensorBoard's import (seconds on some machines) beside the compile
    tensorboard = pool.submit(metrics.import_tensorboard)
    pool.shutdown(wait=False)
    programs, compile_s = compile_programs(config, placement.devices)
    building = chunk_building(programs)
    console.print(f"{programs.origin} in {compile_s:.1f} s ({time.time() - launch_time:.1f} s after launch)"
                  + building_note(programs))
    startup.update(programs=programs.origin, compile_s=round(compile_s, 2),
                   launch_to_compiled_s=round(time.time() - launch_time, 2))
    mngr = checkpoint.manager(run_dir, keep=t_cfg.keep_checkpoints, create=True)
    metrics_path = run_dir / runs.METRICS_FILE
    total = placement.put_replicated(np.asarray(plan.total_env_steps, np.int32))

    if resume:
        state, done_chunks, wall_before, pending, best, last_rows = _resume(
            mngr, programs.state_shape, placement, config, plan, metrics_path, console, primary)
    else:
        state = programs.init(keys, total)
        done_chunks, wall_before, pending, best, last_rows = 0, 0.0, metrics.empty_pending(len(seeds)), None, []
        if primary:
            metrics.write_header(metrics_path)
    startup["launch_to_initialised_s"] = round(time.time() - launch_time, 2)
    env_steps = done_chunks * plan.steps_per_chunk
    if primary:
        writer = tensorboard.result().SummaryWriter(str(run_dir / runs.TB_DIR), purge_step=env_steps if resume else None)
    else:
        writer = _NoWriter()
    last_eval = metrics.eval_success(last_rows)
    videos = tb_video.TrialVideo(config, writer, console, primary)   # train.video_every

    def wall() -> float:
        return wall_before + time.time() - launch_time

    def record(steps: int, taken: dict, updates, ev: dict, trained: dict, policy):
        nonlocal best, last_eval
        if t_cfg.track_best_policy:
            best, _ = best_policy.update(best, policy(), ev, steps)
        rows = metrics.eval_rows(config, seeds, steps, wall(), taken, ev, trained, updates)
        if primary:
            metrics.append_rows(metrics_path, rows)
        for k, v in ev.items():  # every metric the evaluation returns, mean over seeds
            writer.add_scalar(f"eval/{k}", float(np.mean(v)), steps)
        last_eval = metrics.eval_success(rows)
        videos.after_evaluation(policy, steps, final=steps >= plan.total_env_steps)

    def save(state, steps: int, chunks: int):
        meta = {"env_steps": steps, "chunk": chunks, "wall_time_s": wall(), "pending": evaluations.pending,
                "name": config.name}
        best_params = None
        if best is not None:  # each seed's best evaluated policy so far (docrl_jax.train.best_policy)
            meta["best"] = best_policy.to_meta(best)
            best_params = jax.tree.map(placement.put_seeds, best.params)
        # The run's policy is the actor's Polyak average (= the trained actor unless averaged).
        checkpoint.save(mngr, steps, state, state.agent.actor_average, meta, best_params)

    def check(m: dict, steps_before: int) -> bool:
        bad = np.asarray(m["nonfinite_iter"])
        if np.any(bad >= 0):
            i = int(np.argmax(bad >= 0))
            at = steps_before + (int(bad[i]) + 1) * config.env.num_envs
            last = mngr.latest_step()
            console.print(f"[bold red]non-finite loss[/] at env step {at} (seed {seeds[i]}); training stopped. "
                          f"Last good checkpoint: {'none' if last is None else f'env step {last}'} in "
                          f"{run_dir / checkpoint.CHECKPOINT_DIR}")
            return False
        return True

    display = _Display(console, config.name, plan.total_env_steps, env_steps, show_progress)

    def show(m: dict, steps: int, sps: float, eta: str):
        if primary and not startup.get("launch_to_first_chunk_s"):  # start-up as a user sees it
            startup.update(launch_to_first_chunk_s=round(time.time() - launch_time, 2), device=sharding.device_line())
            if building and programs.chunk.ready_at is not None:   # the chunk compiled on after the others
                startup["launch_to_chunk_compiled_s"] = round(programs.chunk.ready_at - launch_time, 2)
            (run_dir / runs.STARTUP_FILE).write_text(json.dumps(startup, indent=1))
        if primary and building and programs.chunk.full is None and "quick_chunks" not in startup:
            # the chunk just run was the full build's first: the quick build ran the ones before
            startup.update(quick_chunks=programs.chunk.quick_calls, launch_to_full_chunk_s=round(time.time() - launch_time, 2))
            (run_dir / runs.STARTUP_FILE).write_text(json.dumps(startup, indent=1))
        metrics.log_chunk(writer, m, steps, sps)
        display.chunk(steps, sps, eta, metrics.stats_line(m, last_eval))

    # save is collective: every process
    hooks = Hooks(check=check, record=record, show=show, save=save)
    evaluations = Evaluations(programs, placement, seeds, hooks,
                              trained_actor=t_cfg.eval_trained_actor and config.agent.policy_average_tau < 1.0,
                              pending=pending)
    evals = Cadence(t_cfg.eval_every, t_cfg.eval_every_minutes)
    saves = Cadence(t_cfg.checkpoint_every, t_cfg.checkpoint_every_minutes)
    # The writer and the checkpoints are closed however the loop ends (a third Ctrl-C too: the process
    # then leaves without Python's shutdown, docrl_jax.console.exit_process).
    with contextlib.closing(mngr), contextlib.closing(writer), Interrupt(console) as interrupt, display.live(), \
            contextlib.closing(videos):
        newest = mngr.latest_step()
        interrupt.newest = "none yet" if newest is None else f"env step {newest:,}"
        if not resume:
            state = evaluations.first(state)
            evals.done()
        # Initialised and evaluated at step 0 (alongside: that evaluation begins with the first chunk).
        startup["launch_to_training_s"] = round(time.time() - launch_time, 2)
        state, done_chunks, status = run_chunks(
            plan, programs.chunk, state, done_chunks, hooks, evaluations, evals, saves, interrupt, get=placement.get,
            any_process=placement.any_process, num_seeds=len(seeds), stop_after_chunks=stop_after_chunks)
    env_steps = done_chunks * plan.steps_per_chunk
    if status == EXIT_OK:
        console.print(f"done: {env_steps:,} env steps per seed in {wall():.0f} s; outputs in {run_dir}")
    elif status == EXIT_INTERRUPTED:
        console.print(f"interrupted: checkpoint saved at env step {env_steps:,}; resume with "
                      f"python -m docrl_jax.train --run-dir {run_dir} --resume")
    if line := still_compiling_line(programs):
        console.print(line)
    return status
