"""`python -m docrl_jax.robustness`: the robustness benchmark (docrl_jax.evaluate.robustness) of one
or several policies side by side, and its files (docrl_jax.evaluate.robustness_report).

    python -m docrl_jax.robustness --run runs/d --out robustness/d
    python -m docrl_jax.robustness --run runs/d0 runs/d1 runs/d2 --run runs/s --policy bba --out robustness/all
    python -m docrl_jax.robustness --policy bba --quick --perturbations wind_gusts,motor_lag --out robustness/bba
    python -m docrl_jax.robustness --run runs/d --tests tanks,structured --tank my_tanks/ --out robustness/tanks
    python -m docrl_jax.robustness --list

A method is each `--run` (its run directories are the method's seeds, as for `python -m
docrl_jax.evaluate`; `--seed-index`, `--which` as there) and `--policy bba`; `--label` names them,
once per method in that order. Where a method has several seeds, robustness.md and robustness.png
show the median over seeds. Outputs under `--out DIR` (its parent must exist): robustness.csv,
robustness.json, robustness.md, robustness.png. Bad input is one line and exit status 2, before
anything is compiled.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Sequence

from docrl_jax.arguments import OneLineParser, check_out, parse_names, prog
from docrl_jax.errors import RunDirError, os_error_line
from docrl_jax import flags, pretrained
from docrl_jax.evaluate import cli, policies, robustness, rollout, run_dirs, tank_sets
from docrl_jax.evaluate import robustness_report as report_files
from docrl_jax.evaluate.protocol import DEFAULT_EVAL_ENV
from docrl_jax.evaluate.robustness import ENVELOPE, PERTURBATIONS, TESTS, Method
from docrl_jax.evaluate.rollout import MEDIA_KEYS

DEFAULT_TANK = "gallery"   # the tanks test's set: every packaged tank
QUICK = {"trials": 10, "layouts": 10}   # --quick: these counts and each perturbation's strongest magnitude


UsageError = cli.UsageError


def parse_tests(text: str) -> list[str]:
    """--tests: test names, exactly (docrl_jax.evaluate.robustness.TESTS), in the benchmark's order."""
    chosen = parse_names("--tests", text.lower(), TESTS, "test", " (comma-separated)")
    return [t for t in TESTS if t in chosen]


def parse_perturbations(text: str) -> list[str]:
    """--perturbations: names of the envelope, all or none."""
    text = text.strip().lower()
    if text == "all":
        return list(PERTURBATIONS)
    if text == "none":
        return []
    return parse_names("--perturbations", text, PERTURBATIONS, "perturbation", " (comma-separated), all or none")


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog=prog("robustness"), description=__doc__.split("\n\n")[0])
    flags.add(p, "--run", ", or several of one config (separate launches: the method's seeds); give --run again for "
                          "another method beside it", metavar="RUN_DIR", nargs="+", action="append")
    flags.add(p, "--policy", f" beside the runs: {', '.join(pretrained.POLICY_NAMES)} (the baseline bba, or a policy "
                             "shipped in the package, docrl_jax/pretrained)", metavar="NAME")
    p.add_argument("--label", action="append", metavar="NAME",
                   help="a method's name in the tables, once per method in order (each --run, then --policy)")
    p.add_argument("--seed-index", default="all",
                   help="seed(s) of each --run, comma-separated, or 'all' (default: every seed the run trained)")
    cli.add_which_argument(p)
    cli.add_guide_argument(p)
    p.add_argument("--bba-depth-phase", default="after", help="BBA only: after (default), first, concurrent, in_air")
    p.add_argument("--tests", default=",".join(TESTS), help=f"comma-separated: {', '.join(TESTS)} (default all)")
    p.add_argument("--perturbations", default="all",
                   help=f"comma-separated names of the envelope ({', '.join(PERTURBATIONS)}), all (default) or none")
    flags.add(p, "--scenarios", " of the perturbations and random trips (default 1,2,3)", default="1,2,3")
    flags.add(p, "--directions", " (default both)", default="air_to_water,water_to_air")
    flags.add(p, "--trials", " per scenario, direction and setting of the perturbations and random trips, and trips "
                             "each way of the tanks test (default 100)", default=None)
    p.add_argument("--layouts", type=int, default=None,
                   help="held-out layouts and held-out structured layouts, one trip each way in each (default 1000)")
    flags.add(p, "--tank", f": the tanks test's set (default {DEFAULT_TANK}); --trials trips each way, trip i in "
                           "tank i mod the set's size", metavar="PATH|DIR|NAME")
    p.add_argument("--quick", action="store_true",
                   help=f"a small sweep: {QUICK['trials']} trials, {QUICK['layouts']} layouts and each perturbation's "
                        "strongest magnitude (--trials and --layouts still win); where the tanks test has fewer trips "
                        "than its set has tanks, as many tanks spread evenly over the set (said when it starts)")
    p.add_argument("--max-steps", type=int, default=500, help="step limit of a trial (default 500, the paper's)")
    p.add_argument("--seed", type=int, default=0, help="base PRNG seed of the trials (default 0, the evaluator's)")
    p.add_argument("--env", action="append", default=[], metavar="KEY=VALUE",
                   help="env parameter override under every test (repeatable), as for python -m docrl_jax.evaluate")
    flags.add(p, "--out", ": a folder, robustness.csv, .json, .md, .png (its parent must exist)", metavar="DIR")
    p.add_argument("--list", action="store_true", help="print the perturbation envelope and exit")
    return p


def validate_args(args: argparse.Namespace) -> dict[str, Any]:
    """Checks the command line before anything is compiled; raises UsageError naming the valid choices."""
    from docrl_jax.baselines.bba import DEPTH_PHASES
    from docrl_jax.envs.layouts import HELD_OUT_IDS
    if not args.run and args.policy is None:
        raise UsageError("nothing to benchmark: give --run RUN_DIR (repeatable) and/or --policy NAME "
                         f"({', '.join(pretrained.POLICY_NAMES)})")
    if args.policy is not None:
        try:
            pretrained.check_name(args.policy)
        except pretrained.UnknownPolicy as e:
            raise UsageError(str(e)) from None
    cli.check_guide(args)
    if args.bba_depth_phase not in DEPTH_PHASES:
        raise UsageError(f"--bba-depth-phase {args.bba_depth_phase!r}: valid choices are {', '.join(DEPTH_PHASES)}")
    trials = args.trials if args.trials is not None else (QUICK["trials"] if args.quick else 100)
    num_layouts = args.layouts if args.layouts is not None else (QUICK["layouts"] if args.quick else 1000)
    for flag, value in (("--trials", trials), ("--max-steps", args.max_steps)):
        flags.check_positive(flag, value)
    if not 0 < num_layouts <= HELD_OUT_IDS:
        raise UsageError(f"--layouts {num_layouts}: must be in 1..{HELD_OUT_IDS} (the held-out layout ids)")
    tests = parse_tests(args.tests)
    scenarios = flags.parse_scenarios(args.scenarios)
    cfg = {"tests": tests, "scenarios": scenarios, "directions": flags.parse_directions(args.directions),
           "trials": trials, "layouts": num_layouts, "seed_indices": cli.parse_seed_indices(args.seed_index),
           "perturbations": parse_perturbations(args.perturbations), "max_steps": args.max_steps, "seed": args.seed,
           "which": args.which, "bba_depth_phase": args.bba_depth_phase, "guide": args.guide}
    cfg["env"] = cli.parse_env_overrides(args.env, _scenarios_run(cfg))
    for key in MEDIA_KEYS:
        if key in cfg["env"]:
            raise UsageError(f"--env {key}: set by the benchmark (random and layout trips force the media of each "
                             "direction)")
    if "tank" in cfg["env"]:
        raise UsageError("--env tank: the tanks test's set is --tank (the other tests fly their own tanks)")
    if args.tank is not None and "tanks" not in tests:
        raise UsageError(f"--tank {args.tank}: only the tanks test flies a tank set; add tanks to --tests")
    cfg["tank"] = (args.tank or DEFAULT_TANK) if "tanks" in tests else None
    cfg["settings"] = robustness.sweep_settings(cfg["perturbations"], args.quick)
    cfg["methods"] = methods_of(args, cfg["seed_indices"])
    _check_settings(cfg, args.max_steps)
    cfg["out"] = output_dir(args.out)
    if cfg["tank"] is not None:   # a bad set: one line, before anything compiles
        cfg["tank_names"] = tank_sets.check(cfg["tank"], rollout.eval_params(0, args.max_steps, **cfg["env"]))
        if args.quick and trials < len(cfg["tank_names"]):   # fewer trips than tanks: a sample of the whole set
            cfg["tank_sample"] = tank_sets.spread(len(cfg["tank_names"]), trials).tolist()
    check_memory(cfg)
    return cfg


def check_memory(cfg: dict) -> None:
    """--trials and --layouts against this machine's memory (trial_memory): one rollout's trials at a time,
    started from states (the perturbations' plants, the trips' layouts); rows are summaries only."""
    from docrl_jax.evaluate import trial_memory
    need = trial_memory.Need(cfg["max_steps"], from_states=True)
    free = trial_memory.free_memory()
    if any(t in cfg["tests"] for t in ("perturbations", "random_trips", "tanks")):
        trial_memory.check("--trials", cfg["trials"], need, free=free)
    if any(t in cfg["tests"] for t in ("held_out_layouts", "structured")):
        trial_memory.check("--layouts", cfg["layouts"], need, unit="layouts", free=free)


def _scenarios_run(cfg: dict) -> list[int]:
    """The scenarios some test of `cfg` runs in: the layout and tank tests' is 0."""
    return [*cfg["scenarios"], 0] if any(t in robustness.LAYOUT_TESTS for t in cfg["tests"]) else cfg["scenarios"]


def _check_settings(cfg: dict, max_steps: int) -> None:
    """Every env the run builds is valid for every scenario it runs in (e.g. --env against the envelope),
    with each method's vehicle."""
    scenarios = _scenarios_run(cfg)
    for vehicle in {json.dumps(m.vehicle, sort_keys=True): m.vehicle for m in cfg["methods"]}.values():
        base = rollout.flown_env(vehicle, cfg["env"])
        host_kw = robustness.host_overrides(base, cfg["settings"])
        for scenario in scenarios:
            for s in cfg["settings"]:
                for kw in ({**base, **s.overrides}, host_kw):
                    try:
                        rollout.eval_params(scenario, max_steps, **kw)
                    except (ValueError, TypeError) as e:
                        raise UsageError(f"{s.perturbation} {s.magnitude} with --env"
                                         + (f" and the vehicle {vehicle}" if vehicle else "")
                                         + f" in scenario {scenario}: {e}") from None


def methods_of(args, seed_indices: list[int] | None) -> list[Method]:
    """The methods of the command line in order (each --run group, then --policy), labelled."""
    from docrl_jax import runs
    from docrl_jax.baselines import bba
    methods = []
    for group in args.run or []:
        for run in group:
            run_dirs.check_run_dir(run)
            bad = [s for s in seed_indices or [] if s >= run_dirs.run_num_seeds(run)]
            if bad:
                raise UsageError(f"--seed-index {bad[0]}: {run} trained {run_dirs.run_num_seeds(run)} seed(s) "
                                 f"(valid 0..{run_dirs.run_num_seeds(run) - 1})")
        sources = [(run, s) for run in group
                   for s in (seed_indices if seed_indices is not None else range(run_dirs.run_num_seeds(run)))]
        numbers = [s for _, s in sources] if len(group) == 1 else list(range(len(sources)))
        names = {run_dirs.config_name(run) for run in group}
        if len(group) > 1 and len(names) != 1:
            name = None   # needs --label
        else:
            name = names.pop() if len(group) > 1 else Path(group[0]).resolve().name
        kept = group_policy(group, args.which)
        if name is not None:
            name = runs.policy_label(name, kept)
        vehicles = {json.dumps(run_dirs.run_vehicle(run), sort_keys=True) for run in group}
        if len(vehicles) > 1:
            raise UsageError(f"--run {' '.join(group)}: the runs fly different vehicles ({'; '.join(sorted(vehicles))}, "
                             "from their config.yaml env sections); give each vehicle its own --run")
        methods.append(Method(name, list(group), sources, numbers, run_dirs.run_vehicle(group[0])))
    if args.policy in pretrained.PRETRAINED:
        methods.append(Method(args.policy, None, [(None, None)], [None], pretrained.vehicle(args.policy), args.policy))
    elif args.policy is not None:
        methods.append(Method(bba.label(args.bba_depth_phase), None, [(None, None)], [None]))
    labels = args.label or []
    if labels and len(labels) != len(methods):
        raise UsageError(f"--label given {len(labels)} time(s) for {len(methods)} method(s): give one --label per "
                         "method, in order (each --run, then --policy), or none")
    for m, label in zip(methods, labels):
        m.label = label
    if args.guide and not labels:   # labels the command made say the methods fly guided
        for m in methods:
            m.label = m.label and policies.guided_label(m.label, args.guide)
    for m in methods:
        if m.label is None:
            raise UsageError(f"--run {' '.join(m.runs)}: the run directories hold different configs "
                             f"({', '.join(sorted({run_dirs.config_name(r) for r in m.runs}))}); benchmark one config "
                             "per --run, or name the method with --label")
    labels = [m.label for m in methods]
    if len(set(labels)) != len(labels):
        raise UsageError(f"methods share a label ({', '.join(labels)}): give each method its own --label")
    return methods


def group_policy(group: list[str], which: str | None) -> str:
    """The policy ("final" or "best") that --which loads from every run directory of one --run: the same in
    each, or a UsageError (one method's seeds are all final or all best policies)."""
    from docrl_jax import runs
    kept = {run: runs.checkpoint_policy(run, which) for run in group}
    if len(set(kept.values())) > 1:
        raise UsageError(f"--run {' '.join(group)}: the runs keep different policies ("
                         + ", ".join(f"{Path(r).name} {w}" for r, w in kept.items())
                         + "; best where train.track_best_policy kept one): give --which final, or each its own --run")
    return kept[group[0]]


def output_dir(out: str | None) -> Path:
    """--out: a folder whose parent exists (created if it does not exist itself)."""
    if out is None:
        raise UsageError("--out DIR: where robustness.csv, .json, .md and .png go (its parent folder must exist)")
    return check_out(out, parents=False)


def envelope_text() -> str:
    lines = ["The perturbation envelope (env overrides per magnitude; the nominal row has none):"]
    for p in ENVELOPE:
        mags = ", ".join(f"{p.label(v)}: {p.param}={p.overrides(v)[p.param]}" for v in p.magnitudes)
        lines.append(f"  {p.name:15s} {p.title}: {p.doc}\n  {'':15s} {mags}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.list:
        print(envelope_text())
        return 0
    try:
        cfg = validate_args(args)
    except (UsageError, RunDirError) as e:
        parser.error(str(e))  # exits with status 2 and the usage line
    except tank_sets.TankSetError as e:   # a tank file's error: its own line, no usage block
        parser.exit(2, f"{parser.prog}: error: {e}\n")
    try:
        cfg["out"].mkdir(exist_ok=True)
        return _benchmark(args, cfg, argv)
    except RunDirError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # an output folder that cannot be written
        print(f"error: {os_error_line(e)}", file=sys.stderr)
        return 2


def metadata(args, cfg: dict, argv: Sequence[str] | None, wall_time_s: float) -> dict:
    """The run's settings: command, versions, date, device, what ran and how many trials."""
    import jax
    return {
        "command": " ".join(["python -m docrl_jax.robustness", *(argv if argv is not None else sys.argv[1:])]),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"), "versions": report_files.versions(),
        "jax_backend": jax.default_backend(), "devices": [str(d) for d in jax.devices()],
        "methods": [{"label": m.label, "runs": m.runs, "seeds": {str(i): {"run": r, "seed_index": s}
                                                                for i, (r, s) in zip(m.seed_indices, m.sources)}}
                    for m in cfg["methods"]],
        "which": {m.label: group_policy(m.runs, args.which) for m in cfg["methods"] if m.runs},
        "bba_depth_phase": args.bba_depth_phase if args.policy else None, "guide": args.guide,
        "tests": cfg["tests"], "scenarios": cfg["scenarios"], "directions": cfg["directions"],
        "trials": cfg["trials"], "layouts": cfg["layouts"], "tank": cfg["tank"], "tank_names": cfg.get("tank_names"),
        "tank_sample": None if cfg.get("tank_sample") is None else [cfg["tank_names"][i] for i in cfg["tank_sample"]],
        "max_steps": args.max_steps, "seed": args.seed,
        "quick": args.quick, "env_overrides": {**DEFAULT_EVAL_ENV, **cfg["env"]},
        "vehicles": {m.label: m.vehicle for m in cfg["methods"]},
        "host_env_overrides": {m.label: robustness.host_overrides(rollout.flown_env(m.vehicle, cfg["env"]),
                                                                  cfg["settings"]) for m in cfg["methods"]},
        "perturbations": {name: {"parameter": PERTURBATIONS[name].param, "doc": PERTURBATIONS[name].doc,
                                 "magnitudes": {s.magnitude: s.overrides for s in cfg["settings"]
                                                if s.perturbation == name}}
                          for name in cfg["perturbations"]} if "perturbations" in cfg["tests"] else {},
        "wall_time_s": round(wall_time_s, 2),
    }


def sample_line(cfg: dict) -> str | None:
    """The line that says which tanks a --quick tanks test flies, where it flies a sample of its set."""
    sample = cfg.get("tank_sample")
    if sample is None:
        return None
    names = cfg["tank_names"]
    return (f"--quick: the tanks test flies {len(sample)} of the {len(names)} tanks of {cfg['tank']}, spread evenly "
            f"over the set: {', '.join(names[i] for i in sample)}")


def _benchmark(args, cfg: dict, argv: Sequence[str] | None) -> int:
    t0 = time.time()
    if sample_line(cfg):
        print(sample_line(cfg), flush=True)
    rows = robustness.run_benchmark(cfg["methods"], cfg, report=lambda line: print(line, flush=True))
    meta = metadata(args, cfg, argv, time.time() - t0)
    paths = report_files.write_outputs(cfg["out"], rows, meta, PERTURBATIONS)
    print(report_files.markdown(rows, meta, PERTURBATIONS))
    print(f"wrote {', '.join(str(p) for p in paths)} ({meta['wall_time_s']} s)")
    return 0


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
