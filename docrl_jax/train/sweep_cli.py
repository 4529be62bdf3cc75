"""`python -m docrl_jax.sweep` (`docrl sweep`): the sweep's command line. It answers --help and reads its
arguments before it imports the sweep itself (docrl_jax.train.sweep: JAX, MJX, Flax), which it runs.

    python -m docrl_jax.sweep --config td3_lstm --grid agent.actor_lr=1e-4,3e-4,1e-3 \\
        --grid agent.tau=0.005,0.01 --seeds 3 --run-dir runs/sweep
"""

from __future__ import annotations

import time
from pathlib import Path

from docrl_jax.arguments import OneLineParser, prog
from docrl_jax.errors import ConfigError, RunDirError, os_error_line
from docrl_jax.console import EXIT_CONFIG, make_console, run_main


def build_parser() -> OneLineParser:
    p = OneLineParser(prog=prog("sweep"), description="every combination of a hyperparameter grid x seeds, with as "
                                                      "few compiled programs as the grid allows (docrl_jax.train.sweep)")
    p.add_argument("--config", help="packaged config name or a YAML path (the base of every combination)")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override one base config value (YAML scalar); repeatable")
    p.add_argument("--grid", action="append", default=[], metavar="SECTION.KEY=V1,V2,...",
                   help="values of one swept key; repeatable (every combination of all grids runs)")
    p.add_argument("--seeds", type=int, default=None, help="seeds per combination (default: train.num_seeds)")
    p.add_argument("--run-dir", help="output directory (default runs/sweep-<name>-<UTC time>)")
    p.add_argument("--resume", action="store_true", help="not supported for sweeps (an error)")
    p.add_argument("--compile-cache", default=None, metavar="DIR|off",
                   help="JAX persistent compilation cache folder, as for python -m docrl_jax.train")
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from docrl_jax import runs, sharding
    from docrl_jax.train import sweep
    from docrl_jax.train.program_store import enable_compile_cache
    console = make_console()
    try:
        if args.resume:
            raise RunDirError("sweeps write no checkpoints and cannot be resumed; start the sweep again in a new "
                              "--run-dir (or resume single runs with python -m docrl_jax.train)")
        if not args.config:
            raise ConfigError("--config is required (a packaged name such as td3_lstm, or a YAML path)")
        if args.seeds is not None and args.seeds < 1:
            raise ConfigError(f"--seeds {args.seeds}: must be >= 1")
        grid = sweep.parse_grid(args.grid)
        run_dir = Path(args.run_dir) if args.run_dir else \
            Path("runs") / f"sweep-{Path(args.config).stem}-{time.strftime('%Y%m%d-%H%M%S', time.gmtime())}"
        runs.check_fresh(run_dir)
        combos, groups = sweep.plan(args.config, args.set, grid, args.seeds)
    except (ConfigError, RunDirError) as e:
        console.print(f"[bold red]error:[/] {e}")
        return EXIT_CONFIG
    cache = enable_compile_cache(args.compile_cache)
    console.print(f"[bold]sweep:[/] {len(combos)} combinations x {combos[0].config.train.num_seeds} seeds in "
                  f"{len(groups)} program{'s' * (len(groups) > 1)}; traced keys: "
                  f"{[k for k in grid if k in sweep.TRACED_KEYS] or 'none'}; run directory {run_dir}")
    console.print(f"[bold]device:[/] {sharding.device_line()}")
    console.print(f"[bold]compilation cache:[/] {cache or 'off'}")
    try:
        return sweep.run_sweep(combos, groups, grid, run_dir, console)
    except OSError as e:
        console.print(f"[bold red]error:[/] {os_error_line(e)}")
        return EXIT_CONFIG


if __name__ == "__main__":
    run_main(main)
