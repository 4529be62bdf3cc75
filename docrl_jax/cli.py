"""`python -m docrl_jax.train`: runs the compiled chunk repeatedly and, between chunks, logs,
evaluates and checkpoints. See `docrl_jax.train` for what one chunk does.

    python -m docrl_jax.train --config td3_lstm [--set section.key=value ...] [--run-dir DIR]
    python -m docrl_jax.train --run-dir DIR --resume [--set train.total_env_steps=...]
    srun ... python -m docrl_jax.train --distributed --config ... --run-dir SHARED_DIR   (docs/TRAINER.md)

Exit codes: 0 done, 2 bad config or run directory, 3 non-finite loss, 130 interrupted (checkpoint saved).

Compiled programs are kept in JAX's persistent compilation cache, so a second launch of the same
config (any seed, length or run directory) skips compilation: by default in
$XDG_CACHE_HOME/docrl_jax/jax (~/.cache/docrl_jax/jax); `--compile-cache DIR` or the environment
variable DOCRL_JAX_COMPILE_CACHE choose another folder, and `off` disables it.
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import functools
import json
import math
import os
import signal
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from rich.console import Console, Group
from rich.live import Live
from rich.text import Text
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
from rich.syntax import Syntax

from jax.sharding import NamedSharding, PartitionSpec

from docrl_jax import best_policy, checkpoint, sharding
from docrl_jax.config import Config, ConfigError, load_config, to_yaml
from docrl_jax.policy import RunDirError
from docrl_jax.run_dir import (CONFIG_FILE, METRIC_COLUMNS, METRICS_FILE, TB_DIR, accumulate, append_rows,
                                empty_pending, eval_rows, read_config, truncate_metrics)
from docrl_jax.train import make_trainer

EXIT_OK, EXIT_CONFIG, EXIT_NONFINITE, EXIT_INTERRUPTED = 0, 2, 3, 130
STARTUP_FILE = "startup.json"   # compile time and launch-to-first-chunk seconds of the latest launch
_EVAL_SALT = 0x5EA1


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m docrl_jax.train", description=__doc__.split("\n\n")[0])
    p.add_argument("--config", help="packaged config name (td3_lstm, sac_lstm, ddpg_mlp, sac_mlp) or a YAML path")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one config value (YAML scalar); repeatable")
    p.add_argument("--run-dir", help="output directory (default runs/<name>-<UTC time>)")
    p.add_argument("--resume", action="store_true", help="continue the run in --run-dir from its latest checkpoint")
    p.add_argument("--no-progress", action="store_true", help="print one line per chunk instead of a progress bar")
    p.add_argument("--compile-cache", default=None, metavar="DIR|off",
                   help="JAX persistent compilation cache folder (default $DOCRL_JAX_COMPILE_CACHE, else "
                        "~/.cache/docrl_jax/jax); 'off' disables it")
    p.add_argument("--distributed", action="store_true",
                   help="one of several processes (hosts, or one per GPU): jax.distributed.initialize() from "
                        "JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES/JAX_PROCESS_ID or the cluster (SLURM srun, "
                        "Open MPI); implied when JAX_COORDINATOR_ADDRESS and JAX_NUM_PROCESSES are set. "
                        "Seeds are split over every process's devices; process 0 writes the outputs")
    return p


def default_compile_cache() -> str:
    env = os.environ.get("DOCRL_JAX_COMPILE_CACHE")
    if env:
        return env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "docrl_jax", "jax")


def enable_compile_cache(path: str | None) -> str | None:
    """Turns on JAX's persistent compilation cache in `path` (None: the default; 'off': disabled).
    Returns the folder used, or None. Programs that compile in under a second are not stored."""
    path = default_compile_cache() if path is None else path
    if path.lower() in ("off", "none", ""):
        return None
    os.makedirs(path, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


def device_line() -> str:
    """What the run is on, for the console: 'GPU: NVIDIA H100 80GB HBM3 (1 device)' or a CPU warning."""
    devs = jax.devices()
    kind = devs[0].platform
    if kind == "cpu":
        return (f"CPU ({os.cpu_count()} cores): no GPU found, training will be slow; the packaged defaults "
                f"are sized for one GPU (see the ETA)")
    return f"{kind.upper()}: {devs[0].device_kind} ({len(devs)} device{'s' if len(devs) > 1 else ''})"


def main(argv: list[str] | None = None) -> int:
    launch = time.time()
    args = build_parser().parse_args(argv)
    console = Console()
    notes: list[str] = []
    try:
        if args.distributed or sharding.distributed_from_env():
            sharding.initialize_distributed()  # before anything touches a device
            if not sharding.is_primary():
                console = Console(quiet=True)
            if not args.run_dir:
                raise RunDirError("a multi-process run needs --run-dir: one directory every process can reach "
                                  "(a shared file system when the processes are on several hosts)")
        config, run_dir = _resolve(args, notes)
    except (ConfigError, RunDirError) as e:
        console.print(f"[bold red]error:[/] {e}")
        return EXIT_CONFIG
    cache = enable_compile_cache(args.compile_cache)
    console.print(f"[bold]run directory:[/] {run_dir}")
    console.print(Syntax(to_yaml(config), "yaml", theme="ansi_dark"))
    console.print(f"[bold]device:[/] {device_line()}")
    for note in notes:
        console.print(f"[bold]chosen for this device:[/] {note}")
    console.print(f"[bold]compilation cache:[/] {cache or 'off'}")
    return run(config, run_dir, resume=args.resume, console=console, show_progress=not args.no_progress,
               launch_time=launch)


def _resolve(args, notes: list | None = None) -> tuple[Config, Path]:
    if args.resume:
        if not args.run_dir:
            raise RunDirError("--resume needs --run-dir DIR")
        if args.config:
            raise ConfigError("--resume takes the config from the run directory's config.yaml; drop --config "
                              "(use --set to change e.g. train.total_env_steps)")
        run_dir = Path(args.run_dir)
        if (run_dir / "sweep.json").is_file():  # docrl_jax.sweep.SWEEP_FILE (not imported: no cycle)
            raise RunDirError(f"{str(run_dir)!r} is a sweep (docrl_jax.sweep): sweeps write no checkpoints and "
                              f"cannot be resumed; train one combination with --config {run_dir}/cNN/config.yaml")
        read_config(run_dir)  # clear errors for a missing dir or config
        if checkpoint.latest_step(run_dir) is None:
            raise RunDirError(f"{str(run_dir)!r} has no checkpoint to resume from")
        return load_config(run_dir / CONFIG_FILE, args.set, notes=notes), run_dir
    if not args.config:
        raise ConfigError("--config is required (a packaged name such as td3_lstm, or a YAML path)")
    config = load_config(args.config, args.set, notes=notes)
    run_dir = Path(args.run_dir) if args.run_dir else Path("runs") / f"{config.name}-{time.strftime('%Y%m%d-%H%M%S', time.gmtime())}"
    if checkpoint.latest_step(run_dir) is not None:
        raise RunDirError(f"{str(run_dir)!r} already holds a run; pass --resume to continue it or choose another --run-dir")
    return config, run_dir


class _ProgressPanel:
    """The progress bar with the latest statistics on a line of their own (they do not fit beside it)."""

    def __init__(self, progress: Progress):
        self.progress, self.line = progress, "waiting for the first chunk (compiling)"

    def __rich__(self):
        return Group(self.progress.get_renderable(), Text(self.line))


@contextlib.contextmanager
def _nothing():
    yield


class _Interrupt:
    """First Ctrl-C: finish the running chunk, checkpoint, stop. Second: stop at once."""

    def __init__(self):
        self.requested = False
        self._old = None

    def __enter__(self):
        try:
            self._old = signal.signal(signal.SIGINT, self._handle)
        except ValueError:  # not the main thread (e.g. some test runners)
            self._old = None
        return self

    def _handle(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


def eval_keys(seeds: list[int], env_steps: int) -> jax.Array:
    """Keys of the evaluation at `env_steps`: a function of seed and step only, so a resumed run
    evaluates on exactly the episodes an uninterrupted one would."""
    return jnp.stack([jax.random.fold_in(jax.random.fold_in(jax.random.PRNGKey(s), _EVAL_SALT), env_steps)
                      for s in seeds])


def programs(config: Config, traced: bool = False):
    """(init, chunk, evaluate), jitted over the seed axis; the chunk donates its runner state.
    On one device they vmap over the seeds; on several (train.devices, docrl_jax.sharding) they
    take and return arrays sharded over the 'seed' mesh axis (`SeedPlacement.put_seeds`), each
    device running the same on its own seeds. Raises ConfigError for a bad train.devices.

    traced=True (docrl_jax.sweep): init(keys, total, hp) and chunk(state, hp) also take the agent's
    hyperparameters (`algorithms.HParams`, one float32 per seed row, split over devices like the
    seeds), so rows that differ only in them run in one program; the config's own values of those
    fields are then unused (and normalised away, so one compilation serves any such values)."""
    # The programs do not depend on the name, the seed values (keys are arguments), the run length
    # (a runner-state field) or when to evaluate and checkpoint, so one compilation serves them all;
    # memoised so a resume in the same process compiles nothing.
    devices, _ = sharding.seed_devices(config.train)
    return _programs(_program_config(config, traced), devices, traced)


def _program_config(config: Config, traced: bool = False) -> Config:
    """The config with every field that does not shape the compiled programs set to a constant
    (train.devices too: the device tuple is passed beside it; with `traced`, the HParams fields)."""
    from docrl_jax.algorithms.common import hparams_neutral
    train = dataclasses.replace(config.train, seed=0, total_env_steps=1, eval_every=1, checkpoint_every=1,
                                keep_checkpoints=1, devices=0, eval_trained_actor=False)
    agent = hparams_neutral(config.agent) if traced else config.agent
    return dataclasses.replace(config, name="run", train=train, agent=agent)


def _squeeze(tree):
    return jax.tree.map(lambda x: x[0], tree)


def _expand(tree):
    return jax.tree.map(lambda x: x[None], tree)


@functools.lru_cache(maxsize=8)
def _programs(config: Config, devices: tuple, traced: bool = False):
    trainer = make_trainer(config)
    # hp: () for a plain run (the config's constants), (hp,) with a seed axis when traced.
    if config.train.num_seeds // len(devices) > 1:
        init = jax.vmap(trainer.init_total, (0, None, 0)) if traced else jax.vmap(trainer.init_total, (0, None))
        chunk = jax.vmap(trainer.chunk)
    else:
        # One seed (per device): run the unbatched program on the seed axis of size 1. Under vmap,
        # lax.cond with a per-seed predicate becomes a select that computes both branches, so the
        # delayed actor update and the pre-learning phase would cost a full update on every step.
        init = lambda keys, total, *hp: _expand(trainer.init_total(keys[0], total, *_squeeze(hp)))  # noqa: E731
        chunk = lambda state, *hp: _expand(trainer.chunk(_squeeze(state), *_squeeze(hp)))  # noqa: E731
    evaluate = _evaluate_program(config, devices) if traced else None
    if len(devices) == 1:
        return jax.jit(init), jax.jit(chunk, donate_argnums=0), evaluate or jax.jit(_evaluate_fn(config, devices))
    seeds, whole = PartitionSpec(sharding.SEED_AXIS), PartitionSpec()
    hp = (seeds,) if traced else ()
    return (_jit_over_seeds(init, devices, (seeds, whole, *hp)),
            _jit_over_seeds(chunk, devices, (seeds, *hp), donate_argnums=0),
            evaluate or _evaluate_program(config, devices))


def _jit_over_seeds(f, devices: tuple, in_specs: tuple, **jit_kwargs):
    """f jitted over several devices: shard_map gives each device its block of seeds and runs f on
    it alone (no communication); every output keeps the seed axis, sharded the same way. The one
    place multi-device programs are built, so the partitioner workaround applies to all of them."""
    sharding.use_gspmd_partitioner()
    mesh = sharding.SeedPlacement(devices).mesh
    seeds = PartitionSpec(sharding.SEED_AXIS)
    return jax.jit(jax.shard_map(f, mesh=mesh, in_specs=in_specs, out_specs=seeds, check_vma=False),
                   in_shardings=tuple(NamedSharding(mesh, spec) for spec in in_specs),
                   out_shardings=NamedSharding(mesh, seeds), **jit_kwargs)


def _evaluate_fn(config: Config, devices: tuple):
    trainer = make_trainer(config)
    if config.train.num_seeds // len(devices) > 1:
        return jax.vmap(trainer.evaluate)
    return lambda params, keys: _expand(trainer.evaluate(_squeeze(params), keys[0]))


def _evaluate_program(config: Config, devices: tuple):
    """The evaluation does not read HParams, so a sweep's programs share the plain run's (its key
    drops the agent's HParams fields; make_trainer of either config builds the same evaluation)."""
    from docrl_jax.algorithms.common import hparams_neutral
    return _evaluate_jit(dataclasses.replace(config, agent=hparams_neutral(config.agent)), devices)


@functools.lru_cache(maxsize=8)
def _evaluate_jit(config: Config, devices: tuple):
    evaluate = _evaluate_fn(config, devices)
    if len(devices) == 1:
        return jax.jit(evaluate)
    seeds = PartitionSpec(sharding.SEED_AXIS)
    return _jit_over_seeds(evaluate, devices, (seeds, seeds))


def hparams_abstract(config: Config):
    """Shapes of the traced programs' `hp` argument: one float32 per seed row and HParams leaf."""
    from docrl_jax.algorithms.common import HParams
    n = config.train.num_seeds
    return jax.tree.map(lambda _: jax.ShapeDtypeStruct((n,), jnp.float32),
                        HParams.from_agent_config(config.agent))


def compiled_programs(config: Config, traced: bool = False):
    """`programs(config, traced)` compiled ahead of time, the three at once in threads (XLA compiles
    them in parallel, which shortens start-up), memoised like `programs`. Returns (init, chunk,
    evaluate, compile seconds of this call; 0 when memoised)."""
    devices = sharding.seed_devices(config.train)[0]
    key = (_program_config(config, traced), devices, traced)
    if key in _COMPILED:
        return (*_COMPILED[key], 0.0)
    init, chunk, evaluate = programs(config, traced)
    n = config.train.num_seeds
    keys = jax.ShapeDtypeStruct((n, 2), jnp.uint32)
    total = jax.ShapeDtypeStruct((), jnp.int32)
    hp = (hparams_abstract(config),) if traced else ()
    abstract = jax.eval_shape(init, keys, total, *hp)
    # The evaluation of a traced program is the plain one's (_evaluate_program): compiled once.
    eval_key = (_program_config(config, True), devices, "evaluate")
    t0 = time.time()
    with ThreadPoolExecutor(3) as pool:
        jobs = [pool.submit(lambda: init.lower(keys, total, *hp).compile()),
                pool.submit(lambda: chunk.lower(abstract, *hp).compile())]
        if eval_key not in _COMPILED:
            jobs.append(pool.submit(lambda: evaluate.lower(abstract.agent.actor_average, keys).compile()))
        compiled = [j.result() for j in jobs]
    if eval_key not in _COMPILED:
        _COMPILED[eval_key] = compiled.pop()
    _COMPILED[key] = (*compiled, _COMPILED[eval_key])
    return (*_COMPILED[key], time.time() - t0)


_COMPILED: dict = {}


def run(config: Config, run_dir: str | Path, resume: bool = False, console: Console | None = None,
        show_progress: bool = True, launch_time: float | None = None, stop_after_chunks: int | None = None) -> int:
    """Trains (or resumes) `config` into `run_dir`. `stop_after_chunks` acts like a Ctrl-C after that
    many chunks of this call (tests use it to interrupt a run)."""
    from tensorboardX import SummaryWriter

    launch_time = time.time() if launch_time is None else launch_time
    # Several processes (docrl_jax.sharding) run this same loop in step; only process 0 writes files.
    primary = sharding.is_primary()
    console = console if console is not None and primary else Console(quiet=not (show_progress and primary))
    try:
        placement = sharding.seed_placement(config.train)
    except ConfigError as e:
        console.print(f"[bold red]error:[/] {e}")
        return EXIT_CONFIG
    if jax.process_count() > 1:  # every process has read the run directory before process 0 writes to it
        from jax.experimental import multihost_utils
        multihost_utils.sync_global_devices("docrl_jax.cli.run")
    if placement.note:
        console.print(f"[yellow]note:[/] {placement.note}")
    run_dir = Path(run_dir)
    if primary:
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / CONFIG_FILE).write_text(to_yaml(config))
    t_cfg = config.train
    trainer = make_trainer(config)
    seeds = [t_cfg.seed + i for i in range(t_cfg.num_seeds)]
    keys = placement.put_seeds(np.stack([jax.random.PRNGKey(s) for s in seeds]))
    console.print("compiling the training, evaluation and initialisation programs ...")
    init, chunk, evaluate, compile_s = compiled_programs(config)
    console.print(f"compiled in {compile_s:.1f} s ({time.time() - launch_time:.1f} s after launch)")
    startup = {"compile_s": round(compile_s, 2), "launch_to_compiled_s": round(time.time() - launch_time, 2)}
    mngr = checkpoint.manager(run_dir, keep=t_cfg.keep_checkpoints, create=True)
    total = placement.put_replicated(np.asarray(trainer.total_env_steps, np.int32))
    metrics_path = run_dir / METRICS_FILE

    if resume:
        step = mngr.latest_step()
        try:
            # Shapes from the jitted program: a compiled one cannot be traced again.
            abstract = jax.eval_shape(programs(config)[0], keys, total)
            with_best = t_cfg.track_best_policy and checkpoint.has_best(mngr, step)
            state, best_params, meta = checkpoint.restore(
                mngr, step, abstract_state=abstract, sharding=placement.seed_sharding,
                abstract_policy=abstract.agent.actor_average if with_best else None, item="best")
        except Exception as e:
            console.print(f"[bold red]error:[/] cannot restore checkpoint {step} of {run_dir}: {type(e).__name__}: {e}")
            return EXIT_CONFIG
        done_chunks, wall_before, pending = meta["chunk"], meta["wall_time_s"], meta["pending"]
        # A checkpoint from before best-policy tracking starts it afresh at the next evaluation.
        best = best_policy.from_meta(placement.get(best_params), meta["best"]) if with_best else None
        if done_chunks * trainer.steps_per_chunk != meta["env_steps"]:
            console.print(f"[bold red]error:[/] checkpoint {step} was written with another chunk size; "
                          f"train.log_every and env.num_envs cannot change on resume")
            return EXIT_CONFIG
        # A resume may lengthen the run (--set train.total_env_steps=...); schedules follow the new total.
        state = state.replace(total_steps=placement.put_seeds(
            np.full(state.total_steps.shape, trainer.total_env_steps, np.int32)))
        if primary:
            truncate_metrics(metrics_path, step)
        console.print(f"resumed from env step {step} (chunk {done_chunks}/{trainer.num_chunks})")
    else:
        state = init(keys, total)
        done_chunks, wall_before, pending, best = 0, 0.0, empty_pending(len(seeds)), None
        if primary:
            with open(metrics_path, "w", newline="") as fh:
                csv.writer(fh).writerow(METRIC_COLUMNS)
    env_steps = done_chunks * trainer.steps_per_chunk
    writer = SummaryWriter(str(run_dir / TB_DIR), purge_step=env_steps if resume else None) if primary else _NoWriter()

    def wall() -> float:
        return wall_before + time.time() - launch_time

    def save(steps: int):
        policy = state.agent.actor_average  # the run's policy (= the trained actor unless averaged)
        meta = {"env_steps": steps, "chunk": done_chunks, "wall_time_s": wall(), "pending": pending,
                "name": config.name}
        best_params = None
        if best is not None:  # each seed's best evaluated policy so far (docrl_jax.best_policy)
            meta["best"] = best_policy.to_meta(best)
            best_params = jax.tree.map(placement.put_seeds, best.params)
        checkpoint.save(mngr, steps, state, policy, meta, best_params)

    def do_eval(steps: int):
        nonlocal pending, best
        keys = placement.put_seeds(np.asarray(eval_keys(seeds, steps)))
        ev = placement.get(evaluate(state.agent.actor_average, keys))
        if t_cfg.track_best_policy:
            best, _ = best_policy.update(best, placement.get(state.agent.actor_average), ev, steps)
        trained = {}
        if t_cfg.eval_trained_actor and config.agent.policy_average_tau < 1.0:
            trained = placement.get(evaluate(state.agent.actor, keys))  # same episodes, the trained actor
        rows = eval_rows(config, seeds, steps, wall(), pending, ev, trained, placement.get(state.agent.updates))
        if primary:
            append_rows(metrics_path, rows)
        for k, v in ev.items():  # every metric the evaluation returns, mean over seeds
            writer.add_scalar(f"eval/{k}", float(np.mean(v)), steps)
        pending = empty_pending(len(seeds))
        return rows

    last_eval = {}
    if not resume:
        last_eval = _seed_mean(do_eval(0))

    progress = Progress(TextColumn("[bold]{task.description}"), BarColumn(),
                        TextColumn("{task.completed:,.0f}/{task.total:,.0f} env steps"), TextColumn("{task.fields[sps]}"),
                        TimeRemainingColumn(), console=console)
    task = progress.add_task(config.name, total=trainer.total_env_steps, completed=env_steps, sps="")
    panel = _ProgressPanel(progress)
    status = EXIT_OK
    chunks_this_call = 0
    with _Interrupt() as interrupt, Live(panel, console=console, refresh_per_second=4,
                                         transient=False) if show_progress else _nothing():
        while done_chunks < trainer.num_chunks:
            t0 = time.time()
            state, m = chunk(state)
            m = placement.get(m)
            dt = time.time() - t0
            bad = np.asarray(m["nonfinite_iter"])
            if np.any(bad >= 0):
                i = int(np.argmax(bad >= 0))
                at = env_steps + (int(bad[i]) + 1) * config.env.num_envs
                last = mngr.latest_step()
                console.print(f"[bold red]non-finite loss[/] at env step {at} (seed {seeds[i]}); training stopped. "
                              f"Last good checkpoint: {'none' if last is None else f'env step {last}'} in "
                              f"{run_dir / checkpoint.CHECKPOINT_DIR}")
                status = EXIT_NONFINITE
                break
            done_chunks += 1
            chunks_this_call += 1
            if chunks_this_call == 1:  # start-up as a user sees it: launch to the first trained chunk
                startup.update(launch_to_first_chunk_s=round(time.time() - launch_time, 2),
                               first_chunk_s=round(dt, 2), device=device_line())
                if primary:
                    (run_dir / STARTUP_FILE).write_text(json.dumps(startup, indent=1))
            prev, env_steps = env_steps, done_chunks * trainer.steps_per_chunk
            accumulate(pending, m)
            sps = trainer.steps_per_chunk * len(seeds) / dt  # env steps/s of all seeds in this chunk
            _log_chunk(writer, m, env_steps, sps)
            final = done_chunks == trainer.num_chunks
            if final or env_steps // t_cfg.eval_every > prev // t_cfg.eval_every:
                last_eval = _seed_mean(do_eval(env_steps))
            stop = placement.any_process(interrupt.requested) or (stop_after_chunks is not None and
                                                                  chunks_this_call >= stop_after_chunks)
            if final or stop or env_steps // t_cfg.checkpoint_every > prev // t_cfg.checkpoint_every:
                save(env_steps)
            progress.update(task, completed=env_steps, sps=f"{sps:,.0f} steps/s")
            panel.line = _stats_line(m, last_eval)  # the live panel's line; --no-progress prints it
            if not show_progress:
                # At this chunk's pace, evaluations excluded; before every iteration of a chunk learns
                # (train.start_steps) the pace is far faster than the run's, so no ETA yet.
                learning = int(np.min(m["learn_iters"])) >= trainer.iters_per_chunk
                eta = f"ETA {_duration((trainer.num_chunks - done_chunks) * dt)}" if learning else \
                    "ETA once learning starts"
                console.print(f"{env_steps:,} steps  {sps:,.0f} steps/s  "
                              f"{eta}  {panel.line}")
            if stop and not final:
                console.print(f"interrupted: checkpoint saved at env step {env_steps}; resume with "
                              f"--run-dir {run_dir} --resume")
                status = EXIT_INTERRUPTED
                break
    writer.close()
    mngr.close()
    if status == EXIT_OK:
        console.print(f"done: {env_steps:,} env steps per seed in {wall():.0f} s; outputs in {run_dir}")
    return status


class _NoWriter:
    """TensorBoard writer of the processes other than 0."""

    def add_scalar(self, *args, **kwargs):
        pass

    def close(self):
        pass


def _seed_mean(rows: list[dict]) -> dict:
    """Mean over seeds of an evaluation's rows (for the progress line)."""
    return {"success_rate": float(np.mean([r["success_rate"] for r in rows]))}


def _log_chunk(writer, m: dict, env_steps: int, sps: float) -> None:
    eps = float(np.sum(m["episodes"]))
    if eps:
        writer.add_scalar("train/episode_return", float(np.sum(m["return_sum"])) / eps, env_steps)
        writer.add_scalar("train/success_rate", float(np.sum(m["success_sum"])) / eps, env_steps)
    for k in ("critic_loss", "actor_loss", "alpha", "alpha_loss", "q", "policy_freq"):
        if k in m and float(np.sum(m["learn_iters"])):
            writer.add_scalar(f"train/{k}", float(np.mean(m[k])), env_steps)
    writer.add_scalar("train/env_steps_per_s", sps, env_steps)
    writer.add_scalar("train/grad_updates_in_chunk", float(np.mean(m["updates"])), env_steps)


def _stats_line(m: dict, last_eval: dict) -> str:
    eps = float(np.sum(m["episodes"]))
    ret = f"{float(np.sum(m['return_sum'])) / eps:.1f}" if eps else "n/a"
    succ = f"{float(np.sum(m['success_sum'])) / eps:.2f}" if eps else "n/a"
    parts = [f"train return {ret}", f"train success {succ}",
             f"eval success {last_eval.get('success_rate', math.nan):.2f}",
             f"critic {float(np.mean(m['critic_loss'])):.3g}", f"actor {float(np.mean(m['actor_loss'])):.3g}"]
    if "alpha" in m:
        parts.append(f"alpha {float(np.mean(m['alpha'])):.3g}")
    return "  ".join(parts)


def _duration(seconds: float) -> str:
    """'1 h 05 min', '4 min 10 s', '12 s' (the --no-progress line's ETA)."""
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min {s % 60:02d} s" if s >= 60 else f"{s} s"
