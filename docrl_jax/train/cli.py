"""`python -m docrl_jax.train`: trains a config into a run directory, or resumes one.

    python -m docrl_jax.train --config td3_lstm [--set section.key=value ...] [--run-dir DIR]
    python -m docrl_jax.train --config td3_lstm --tank gallery      (train in tank files: docs/TANKS.md)
    python -m docrl_jax.train --run-dir DIR --resume [--set train.total_env_steps=...]
    srun ... python -m docrl_jax.train --distributed --config ... --run-dir SHARED_DIR   (docs/TRAINER.md)

The command line reads its config without importing MuJoCo, Flax or Orbax and starts loading the
stored programs (docrl_jax.train.program_store.prefetch) before it imports the run itself
(docrl_jax.train.run), so that a warm launch's loads and imports overlap.

Exit codes: 0 done, 2 bad config, run directory or file system, 3 non-finite loss, 130 interrupted
(checkpoint saved).

Compiled programs are kept in JAX's persistent compilation cache and, whole, in the program store
inside it (docrl_jax.train.program_store), so a second launch of the same config (any seed, length
or run directory) skips compilation and tracing: by default in $XDG_CACHE_HOME/docrl_jax/jax
(~/.cache/docrl_jax/jax); `--compile-cache DIR` or the environment variable DOCRL_JAX_COMPILE_CACHE
choose another folder, and `off` disables both. "after launch" times count from the process's start.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from docrl_jax import flags
from docrl_jax.arguments import OneLineParser, prog
from docrl_jax.config import Config, env_kwargs, load_config, packaged_config_names, parse_overrides
from docrl_jax.errors import ConfigError, RunDirError
from docrl_jax.console import EXIT_CONFIG, EXIT_INTERRUPTED, EXIT_NONFINITE, EXIT_OK, make_console

__all__ = ["EXIT_CONFIG", "EXIT_INTERRUPTED", "EXIT_NONFINITE", "EXIT_OK", "build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=prog("train"), description=__doc__.split("\n\n")[0])
    p.add_argument("--config", help=f"packaged config name ({', '.join(packaged_config_names())}) or a YAML path")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one config value (YAML scalar); repeatable")
    flags.add(p, "--tank", " to train in: sets env.scenario 0 and env.tank; every tank is checked before anything "
                           "compiles", metavar="PATH|DIR|NAME")
    p.add_argument("--run-dir", help="output directory (default runs/<name>-<UTC time>)")
    p.add_argument("--resume", action="store_true", help="continue the run in --run-dir from its newest intact "
                                                         "checkpoint; --set may change only its length, devices and "
                                                         "cadences (docrl_jax.train.run.RESUMABLE)")
    p.add_argument("--no-progress", action="store_true",
                   help="print one line per chunk instead of a progress bar (always so when the output is not a "
                        "terminal: a log file, a pipe)")
    p.add_argument("--compile-cache", default=None, metavar="DIR|off",
                   help="JAX persistent compilation cache folder (default $DOCRL_JAX_COMPILE_CACHE, else "
                        "~/.cache/docrl_jax/jax); 'off' disables it")
    p.add_argument("--distributed", action="store_true",
                   help="one of several processes (hosts, or one per GPU): jax.distributed.initialize() from "
                        "JAX_COORDINATOR_ADDRESS/JAX_NUM_PROCESSES/JAX_PROCESS_ID or the cluster (SLURM srun, "
                        "Open MPI); implied when JAX_COORDINATOR_ADDRESS and JAX_NUM_PROCESSES are set. "
                        "Seeds are split over every process's devices; process 0 writes the outputs")
    return p



def process_start_time() -> float:
    """When this process started (the wall clock), so 'after launch' includes the imports before
    main(); main()'s own start where the OS does not say (not Linux)."""
    try:
        with open("/proc/self/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])  # field 22, starttime, after the command name
        with open("/proc/uptime") as f:
            uptime = float(f.read().split()[0])
        return time.time() - (uptime - ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return time.time()


def main(argv: list[str] | None = None) -> int:
    launch = process_start_time()
    args = build_parser().parse_args(argv)
    # JAX with the device runtime (seconds): after the command line, so --help and its errors come at once
    from docrl_jax import sharding
    from docrl_jax.train import program_store
    console = make_console()
    notes: list[str] = []
    try:
        distributed = args.distributed or sharding.distributed_from_env()
        if distributed:
            sharding.initialize_distributed()  # before anything touches a device
            if not sharding.is_primary():
                console = make_console(quiet=True)
            if not args.run_dir:
                raise RunDirError("a multi-process run needs --run-dir: one directory every process can reach "
                                  "(a shared file system when the processes are on several hosts)")
        config, run_dir = _resolve(args, notes)
        cache = program_store.enable_compile_cache(args.compile_cache)
        if not distributed:  # (several processes have no program store)
            program_store.prefetch(config)  # the stored programs load while the imports below run
        check_tank(config, "--tank" if args.tank is not None else "env.tank")
        from docrl_jax.train.run import check_run_dir, run  # MuJoCo and MJX, Flax, Orbax: seconds
        if not args.resume:  # (a resume's directory was checked before its config was read)
            check_run_dir(run_dir, resume=False)
    except (ConfigError, RunDirError) as e:
        console.print(f"[bold red]error:[/] {e}")
        return EXIT_CONFIG
    for line in launch_summary(config, run_dir):
        console.print(line)
    console.print(f"[bold]device:[/] {sharding.device_line()}")
    if notes:
        console.print(f"[bold]chosen for this device:[/] {'; '.join(notes)}")
    console.print(f"[bold]compilation cache:[/] {cache or 'off'}")
    status = run(config, run_dir, resume=args.resume, console=console, show_progress=not args.no_progress,
                 launch_time=launch)
    sharding.shutdown_distributed()   # several processes: together, before Python's exit tears the devices down
    return status


def launch_summary(config: Config, run_dir: Path) -> list[str]:
    """What a launch says of its run, in two lines; every key is in the run directory's config.yaml
    (written by docrl_jax.train.run before anything compiles)."""
    from docrl_jax import runs
    a, t = config.agent, config.train
    tank = env_kwargs(config).get("tank")
    where = f"tanks {tank}" if tank is not None else f"env scenario {config.env.scenario}"
    seeds = f"seed {t.seed}" if t.num_seeds == 1 else f"seeds {t.seed}-{t.seed + t.num_seeds - 1}"
    return [f"[bold]run:[/] {config.name}: {a.algo.upper()} with an {a.actor.upper()} actor, {where}, {seeds}, "
            f"{t.total_env_steps:,} env steps per seed",
            f"[bold]run directory:[/] {run_dir} (full config: {run_dir / runs.CONFIG_FILE})"]


def check_tank(config: Config, flag: str = "env.tank") -> None:
    """A run's tank set (env.tank) loads for its env, every rule of docs/TANKS.md checked; its one-line
    error after `flag` (what set it) as a ConfigError. Nothing to do without env.tank."""
    kwargs = env_kwargs(config)
    if kwargs.get("tank") is None:
        return
    from docrl_jax.envs import make_params
    from docrl_jax.evaluate.tank_sets import TankSetError, check
    try:
        check(kwargs["tank"], make_params(config.env.scenario, **kwargs), flag)
    except TankSetError as e:
        raise ConfigError(str(e)) from None


def _resolve(args, notes: list | None = None) -> tuple[Config, Path]:
    """The config and run directory of the command line. A new run's directory is checked later
    (docrl_jax.train.run.check_run_dir), after the stored programs have begun to load."""
    if args.resume:
        if not args.run_dir:
            raise RunDirError("--resume needs --run-dir DIR")
        if args.config or args.tank:
            raise ConfigError(f"--resume takes the config from the run directory's config.yaml; drop "
                              f"{'--config' if args.config else '--tank'} (use --set to change e.g. "
                              "train.total_env_steps)")
        from docrl_jax import runs
        from docrl_jax.train.run import check_resume_changes, check_run_dir
        run_dir = Path(args.run_dir)
        check_run_dir(run_dir, resume=True)
        config = load_config(run_dir / runs.CONFIG_FILE, args.set, notes=notes)
        check_resume_changes(run_dir, config)   # before the launch's summary and its stored programs' prefetch
        return config, run_dir
    if not args.config:
        raise ConfigError("--config is required (a packaged name such as td3_lstm, or a YAML path)")
    overrides = parse_overrides(args.set)
    if args.tank is not None:
        # A file or folder by its absolute path, so that a resume from elsewhere finds it; a name as given.
        spec = Path(args.tank).expanduser()
        overrides.update({"env.scenario": 0, "env.tank": str(spec.resolve()) if spec.exists() else args.tank})
    config = load_config(args.config, overrides, notes=notes)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    run_dir = Path(args.run_dir) if args.run_dir else Path("runs") / f"{config.name}-{stamp}"
    return config, run_dir
