"""`python -m docrl_jax.sweep` (the command line: docrl_jax.train.sweep_cli): every combination of a
hyperparameter grid x seeds, with as few compiled programs as the grid allows.

    python -m docrl_jax.sweep --config td3_lstm --grid agent.actor_lr=1e-4,3e-4,1e-3 \\
        --grid agent.tau=0.005,0.01 --seeds 3 --run-dir runs/sweep

How it runs. The agent's hyperparameters that shape no array (`TRACED_KEYS`: learning rates, tau,
gamma, the noise scales, lr_end_scale, policy_average_tau, SAC's target entropy and initial
temperature) are inputs of the compiled program (`algorithms.HParams`, one float32 per row), so all
combinations that differ only in them run as ONE program whose leading axis is combination x seed:
the `train.num_seeds` axis of a plain run, vmapped and split over the devices exactly as seeds are
(`docrl_jax.train.programs`, traced=True). Every other key (network widths,
num_envs, batch_size, seq_len, env parameters such as reward scales, run length, ...) is compiled
into the program: combinations that differ in such a key form separate groups, run one after
another, each one program. Row r = c x seeds + s of a group trains combination c with seed
train.seed + s, on exactly the episodes and PRNG keys a plain run of that combination's config
would use (same seeds for every combination: differences between them are not seed noise).

Reward scales (`env.progress_reward_scale`, ...) are EnvParams fields closed over by the compiled
environment step, not traced: they can be swept, as separate programs.

Outputs in --run-dir:
    sweep.json              the grid, the combinations and their groups (written before training)
    c<NN>/config.yaml       combination NN's resolved config (num_seeds = --seeds)
    c<NN>/metrics.csv       its rows in the metrics.csv format of a plain run, plus `combination`
                            and one column per swept key; wall_time_s counts from its group's start
                            (compile included) while sharing the devices with the group's other rows
    sweep.csv, sweep.md     (docrl_jax.train.sweep_report) per combination, mean ± std over seeds: time to 90 % success in both
                            paper directions, final success (rate, A-W, W-A), final evaluation return
    curves_<key>.png        success against env steps, one line per value of the swept key, mean
                            over seeds and the other keys' values

The rows run through the same chunk loop as a plain run (docrl_jax.train.loop: evaluation cadence,
Ctrl-C finishes the running chunk and writes the table of what was evaluated). Not supported:
checkpoints and --resume (a sweep is restarted from scratch; --resume is an error), several
processes (--distributed), TensorBoard. A row whose losses become non-finite keeps running (its
rows are independent of the others); the table marks it as diverged.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import time
from pathlib import Path

import numpy as np
import yaml

from docrl_jax import memory, runs, sharding
from docrl_jax.algorithms.common import HPARAM_KEYS, HParams, hparams_neutral
from docrl_jax.config import Config, field_docs, load_config, parse_overrides, to_yaml, validate
from docrl_jax.errors import ConfigError
from docrl_jax.train import metrics
from docrl_jax.console import EXIT_INTERRUPTED, EXIT_OK, make_console
from docrl_jax.train.chunks import schedule
from docrl_jax.train.loop import Cadence, Evaluations, Hooks, Interrupt, run_chunks
from docrl_jax.train.programs import building_note, compile_programs, still_compiling_line
from docrl_jax.train.sweep_report import TABLE_MD, columns, write_summary

SWEEP_FILE = runs.SWEEP_FILE
TRACED_KEYS = tuple(f"agent.{k}" for k in HPARAM_KEYS)
NOT_SWEEPABLE = {
    "name": "the sweep names its combinations c00, c01, ...",
    "train.seed": "the first seed; every combination runs seeds train.seed .. + --seeds - 1",
    "train.num_seeds": "use --seeds",
    "train.devices": "where the rows run, not what they learn (set it with --set)",
    "train.checkpoint_every": "sweeps write no checkpoints",
    "train.keep_checkpoints": "sweeps write no checkpoints",
    "train.track_best_policy": "sweeps write no checkpoints (the best policy lives in them)",
    "train.eval_trained_actor": "set it for the whole sweep with --set",
}


# ------------------------------------------------------------------------------------ the grid
def sweepable_keys() -> list[str]:
    """Every config key a grid may name: the traced ones and the compiled-in ones."""
    from docrl_jax.envs import param_docs
    keys = set(field_docs()) - {"env.overrides"} | {f"env.{k}" for k in param_docs() if k != "scenario"}
    return sorted(keys - set(NOT_SWEEPABLE))


def _split_values(text: str) -> list[str]:
    """'1e-4,3e-4' -> ['1e-4', '3e-4']; commas inside brackets stay ('[64,64],[128,128]')."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch in "[(") - (ch in "])")
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return parts + [cur]


def _number(value):
    """YAML 1.1 reads '1e-4' as text; the config accepts it as a number, so the grid does too."""
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    return value


def parse_grid(items: list[str]) -> dict[str, list]:
    """['agent.tau=0.005,0.01', ...] -> {'agent.tau': [0.005, 0.01], ...} in the given order. Raises
    ConfigError for a malformed item, a repeated key, or a key that is unknown or not sweepable
    (naming the valid keys), before anything is built or compiled."""
    grid: dict[str, list] = {}
    valid = sweepable_keys()
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--grid {item!r}: expected section.key=value1,value2,...")
        key, text = (x.strip() for x in item.split("=", 1))
        if key in grid:
            raise ConfigError(f"--grid {key}: given twice; list all its values in one --grid")
        if key in NOT_SWEEPABLE:
            raise ConfigError(f"--grid {key}: not sweepable ({NOT_SWEEPABLE[key]}); traced keys (one program for "
                              f"all their values): {list(TRACED_KEYS)}; any other key of {valid} runs one "
                              f"program per value")
        if key not in valid:
            raise ConfigError(f"--grid {key}: unknown key; traced keys (one program for all their values): "
                              f"{list(TRACED_KEYS)}; compiled-in keys (one program per value): "
                              f"{[k for k in valid if k not in TRACED_KEYS]}")
        try:
            values = [_number(yaml.safe_load(v)) for v in _split_values(text)]
        except yaml.YAMLError as e:
            raise ConfigError(f"--grid {item!r}: a value is not valid YAML ({e})") from None
        if not values or any(v is None for v in values):
            raise ConfigError(f"--grid {item!r}: empty value; expected section.key=value1,value2,...")
        if len({json.dumps(v) for v in values}) != len(values):
            raise ConfigError(f"--grid {item!r}: a value is repeated")
        grid[key] = values
    if not grid:
        raise ConfigError("no --grid given: at least one --grid section.key=value1,value2,...")
    return grid


@dataclasses.dataclass(frozen=True)
class Combination:
    index: int
    values: dict            # swept key -> value
    config: Config          # the combination's resolved config (num_seeds = --seeds)

    @property
    def name(self) -> str:
        return f"c{self.index:02d}"


@dataclasses.dataclass(frozen=True)
class Group:
    """Combinations that share one compiled program: `config` has num_seeds = rows (combinations x
    seeds) and the HParams fields at their schema defaults (the rows' own values are traced);
    `placement` is where its rows run (resolved once, when the sweep is planned)."""
    config: Config
    combinations: tuple
    placement: sharding.SeedPlacement


def plan(config: str, sets: list[str], grid: dict[str, list], seeds: int | None,
         check_memory: bool = True) -> tuple[list[Combination], list[Group]]:
    """Builds and validates every combination's config and the groups of one program each; raises
    ConfigError (a bad value, too many rows for the devices or their memory) before any compile."""
    base = parse_overrides(sets)
    combos = []
    for i, values in enumerate(itertools.product(*grid.values())):
        chosen = dict(zip(grid, values))
        overrides = {**base, **chosen}
        if seeds is not None:
            overrides["train.num_seeds"] = seeds
        try:
            cfg = load_config(config, overrides)
        except ConfigError as e:
            raise ConfigError(f"combination {', '.join(f'{k}={v}' for k, v in chosen.items())}: {e}") from None
        combos.append(Combination(i, chosen, cfg))
    by_program: dict[Config, list[Combination]] = {}
    for c in combos:
        by_program.setdefault(dataclasses.replace(c.config, agent=hparams_neutral(c.config.agent)), []).append(c)
    groups = []
    for shared, members in by_program.items():
        rows = len(members) * shared.train.num_seeds
        gcfg = dataclasses.replace(shared, name=members[0].config.name,
                                   train=dataclasses.replace(shared.train, num_seeds=rows))
        validate(gcfg)
        placement = sharding.seed_placement(gcfg.train)  # ConfigError for too many rows for the devices
        if check_memory:
            memory.check_memory(gcfg, placement.devices)
        groups.append(Group(gcfg, tuple(members), placement))
    return combos, groups


# ------------------------------------------------------------------------------------ running
def run_sweep(combos: list[Combination], groups: list[Group], grid: dict[str, list], run_dir, console=None) -> int:
    """Trains every group in turn into run_dir; writes the table and figures. Returns an exit code."""
    console = console or make_console()
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / SWEEP_FILE).write_text(json.dumps({
        "grid": grid, "traced_keys": [k for k in grid if k in TRACED_KEYS],
        "combinations": [{"name": c.name, "values": c.values} for c in combos],
        "groups": [[c.name for c in g.combinations] for g in groups]}, indent=1))
    for c in combos:
        d = run_dir / c.name
        d.mkdir(exist_ok=True)
        (d / runs.CONFIG_FILE).write_text(to_yaml(c.config))
        metrics.write_header(d / runs.METRICS_FILE, columns(grid))
    status = EXIT_OK
    diverged: dict[str, list] = {}
    built: list = []   # each group's programs: builds of a tiered start may still compile at the end
    try:
        with Interrupt(console, action="writing the table") as interrupt:
            for i, group in enumerate(groups):
                names = ", ".join(c.name for c in group.combinations)
                console.print(f"[bold]group {i + 1}/{len(groups)}[/] ({names}): {group.config.train.num_seeds} "
                              f"rows in one program")
                status = _run_group(group, grid, run_dir, console, interrupt, diverged, built)
                if status != EXIT_OK:
                    break
    except KeyboardInterrupt:  # the third Ctrl-C: no waiting for the running chunk
        status = EXIT_INTERRUPTED
    if status != EXIT_OK:
        console.print("interrupted: the table covers the evaluations written so far")
    write_summary(run_dir, grid, diverged)
    console.print(f"table: {run_dir / TABLE_MD}")
    for line in dict.fromkeys(still_compiling_line(p) for p in built):
        if line:   # the process waits for them on exit
            console.print(line)
    return status


def _run_group(group: Group, grid: dict, run_dir: Path, console, interrupt: Interrupt,
               diverged: dict[str, list], built: list) -> int:
    """One group's program through the chunk loop: evaluations at step 0, when due and at the end.
    Adds {combination name: [seeds whose losses became non-finite]} to `diverged` and its programs to
    `built`."""
    import jax

    start = time.time()
    cfg, t, placement = group.config, group.config.train, group.placement
    per = group.combinations[0].config.train.num_seeds
    rows = [(c, t.seed + s) for c in group.combinations for s in range(per)]
    seeds = [s for _, s in rows]
    if placement.note:
        console.print(f"[yellow]note:[/] {placement.note}")
    plan = schedule(cfg)
    keys = placement.seed_keys(seeds)
    hp = jax.tree.map(placement.put_seeds, HParams.stack([HParams.from_agent_config(c.config.agent)
                                                          for c, _ in rows]))
    programs, compile_s = compile_programs(cfg, placement.devices, traced=True)
    built.append(programs)
    console.print(f"{programs.origin} in {compile_s:.1f} s{building_note(programs)}")
    total = placement.put_replicated(np.asarray(plan.total_env_steps, np.int32))
    state = programs.init(keys, total, hp)
    trained_actor = [c.config.train.eval_trained_actor and c.config.agent.policy_average_tau < 1.0 for c, _ in rows]

    def record(steps: int, taken: dict, updates, ev: dict, trained: dict, policy):
        out = metrics.eval_rows(cfg, seeds, steps, time.time() - start, taken, ev, trained, updates)
        for row, (c, _), wants in zip(out, rows, trained_actor):
            if not wants:
                for k in metrics.TRAINED_ACTOR_KEYS:
                    row[f"trained_actor_{k}"] = math.nan
            row.update({"combination": c.name, **{k: json.dumps(v) if isinstance(v, list) else v
                                                  for k, v in c.values.items()}})
        for c in group.combinations:
            metrics.append_rows(run_dir / c.name / runs.METRICS_FILE,
                                [r for r in out if r["combination"] == c.name], columns(grid))
        mean = {c.name: metrics.eval_success([r for r in out if r["combination"] == c.name])
                for c in group.combinations}
        console.print(f"{steps:,} env steps, {time.time() - start:.0f} s: eval success "
                      + "  ".join(f"{n} {v:.2f}" for n, v in mean.items()))

    def check(m: dict, steps_before: int) -> bool:
        for i in np.flatnonzero(np.asarray(m["nonfinite_iter"]) >= 0):
            c, s = rows[i]
            if s not in diverged.setdefault(c.name, []):
                diverged[c.name].append(s)
                console.print(f"[bold red]non-finite loss[/] in {c.name} ({c.values}), seed {s}; its rows go on "
                              f"(independent of the others) and the table marks it as diverged")
        return True  # a diverged row does not stop the others

    hooks = Hooks(check=check, record=record, show=lambda *_: None)
    evaluations = Evaluations(programs, placement, seeds, hooks, trained_actor=any(trained_actor))
    evals = Cadence(t.eval_every, t.eval_every_minutes)
    state = evaluations.first(state)
    evals.done()
    _, _, status = run_chunks(plan, programs.chunk, state, 0, hooks, evaluations, evals, None, interrupt,
                              get=placement.get, hp=(hp,), num_seeds=len(rows))
    return status
