"""The 10-seed table of benchmarks/rounds/every_seed.sh from the job's packed results; also the
launches of benchmarks/rounds/recipe_end.sh (named RECIPE_sI: one table per recipe).

    python3 benchmarks/every_seed_table.py round_every_seed.tar [--out every_seed.md]
    python3 benchmarks/every_seed_table.py DIR        (a folder holding pack/, or the pack folder itself)

One table per side of the job (SIDES: sSEED is the new side, old_sSEED the old one, stopped at
90 % without evaluations), its title naming the settings of the runs' config.yaml that set the two sides apart
(NEW_ARGS, OLD_ARGS). Per launch (seed): cold or warm (startup.json: programs compiled or loaded from the job's shared
cache, and the seconds that took); launch to 90 % both ways on the in-training paper pairs (metrics.csv's
wall_time_s, seconds after the process started, of the first evaluation with both directions at the
target: benchmarks/time_to_success.py's `reached`) and the env steps there; launch to end (gpu_lanes'
`times`, whole seconds, from before the command to its exit); the learner's median env steps/s
(benchmarks/ab_summary.py's reading of the log); the in-training evaluation of the final policy (the
last row) and of the best one (the checkpoint's record of the evaluation that picked it); the
evaluator's success of the final and the best policy per scenario and direction. Then medians and
the slowest, and how many finals and bests meet the run goal (docs/BENCHMARKS.md, "Targets"): >= 95 % both ways in scenario 2 and
>= 90 % both ways in scenarios 1 and 3.

The best policy is picked on, and its in-training score measured on, the in-training scenario-2 pair
episodes (docrl_jax/train/best_policy.py): that score is optimistic. The evaluator's columns are other
episodes (other trial keys, hence other starts, wind and policy keys, and 0.01 m range noise the
training evaluation does not draw), so its final-versus-best comparison is honest.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import sys
import tempfile
from pathlib import Path

from docrl_jax.benchmarking import (GOAL, SCENARIO_COLUMNS, TARGET, chunk_steps_per_s, goal_counts, pair, pct, read_rows,
                                    reached, unpack)

from docrl_jax import runs  # noqa: E402
from docrl_jax.config import differences  # noqa: E402
from docrl_jax.errors import RunDirError  # noqa: E402

def launch_times(path: Path) -> dict[str, float]:
    """NAME -> seconds from its `train start` to its `train rc=` line in gpu_lanes' times file."""
    start, end = {}, {}
    for line in path.read_text().splitlines() if path.is_file() else []:
        parts = line.split()
        if len(parts) == 4 and parts[1] == "train":
            (start if parts[2] == "start" else end)[parts[0]] = float(parts[3])
    return {n: end[n] - start[n] for n in end if n in start}


def best_record(run_dir: Path) -> dict | None:
    """The checkpoint's record of the evaluation that picked seed 0's best policy ({env_steps, the
    success fractions}), read by docrl_jax.checkpoint; None without one."""
    from docrl_jax import checkpoint
    step = checkpoint.latest_step(run_dir)
    if step is None:
        return None
    meta = checkpoint.restore(checkpoint.manager(run_dir), step)[2]
    if "best" not in meta:
        return None
    return {"env_steps": meta["best"]["env_steps"][0], **meta["best"]["evaluation"][0]}


def evaluator_success(eval_dir: Path) -> dict | None:
    """{(scenario, direction): success rate} of the evaluator's results.csv in `eval_dir`; None if absent."""
    path = eval_dir / "results.csv"
    if not path.is_file():
        return None
    rows = list(csv.DictReader(open(path)))
    if not rows:
        return None
    return {"trials": int(rows[0]["trials"]), **{(int(r["scenario"]), r["direction"]): float(r["success_rate"])
                                                for r in rows}}


def run_config(run_dir: Path):
    """The run's resolved config, or None where it is missing or no longer loads (an older version's keys)."""
    try:
        return runs.read_config(run_dir)
    except RunDirError:
        return None


def side_settings(launches: list[dict], side: str, other: str) -> dict:
    """{'section.key': value} of the settings that set `side`'s launches apart from `other`'s: keys on which
    every launch of each side agrees and the two sides differ (so not the seed, nor the run's name)."""
    mine = [r["config"] for r in launches if r["side"] == side]
    theirs = [r["config"] for r in launches if r["side"] == other]
    if not mine or not theirs or any(c is None for c in mine + theirs):
        return {}
    varies = {k for cs in (mine, theirs) for c in cs[1:] for k in differences(cs[0], c)}
    return {k: a for k, (a, _) in differences(mine[0], theirs[0]).items() if k not in varies}


def launch(work: Path, run_dir: Path, ends: dict) -> dict:
    name = run_dir.name
    side = name.rsplit("_", 1)[0] if "_" in name else "new"   # the job's names: sSEED, old_sSEED
    rows = read_rows(str(run_dir / "metrics.csv"))
    start = json.loads((run_dir / "startup.json").read_text()) if (run_dir / "startup.json").is_file() else {}
    hit = reached(rows, TARGET)
    last = rows[-1] if rows else None
    log = work / f"{name}.log"
    try:
        rate = chunk_steps_per_s(str(log)) if log.is_file() else None
    except statistics.StatisticsError:  # a run too short to have learning chunks
        rate = None
    return {"name": name, "side": side, "seed": int(float(last["seed"])) if last else None,
            "config": run_config(run_dir),
            "cold": {"compiled": True, "loaded": False}.get(start.get("programs")),
            "compile_s": start.get("compile_s"), "first_chunk_s": start.get("launch_to_first_chunk_s"),
            "time_to_90_s": float(hit["wall_time_s"]) if hit else None,
            "env_steps_at_90": int(float(hit["env_steps"])) if hit else None,
            "launch_to_end_s": ends.get(name), "env_steps_per_s": rate,
            "final_env_steps": int(float(last["env_steps"])) if last else None,
            "train_final": (float(last["success_air_to_water"]), float(last["success_water_to_air"])) if last else None,
            "train_best": best_record(run_dir) if (run_dir / "checkpoints").is_dir() else None,
            "eval_final": evaluator_success(work / "eval" / f"{name}_final"),
            "eval_best": evaluator_success(work / "eval" / f"{name}_best")}


def num(x, fmt: str = ".1f") -> str:
    return "–" if x is None else format(x, fmt)


def secs(x: float) -> str:
    """Seconds to the target; +inf (a launch that never reached it, also as a median) reads 'not reached'."""
    return "not reached" if x == float("inf") else f"{x:.1f} s"


def table(launches: list[dict], gpu: str = "", side: str = "new", settings: dict | None = None) -> str:
    trials = {ev["trials"] for r in launches for ev in (r["eval_final"], r["eval_best"]) if ev}
    head = ["seed", "start (compile s)", "launch to 90 % (s)", "env steps at 90 %", "launch to end (s)",
            "learner (M env steps/s)", "in-training final A-W / W-A", "in-training best A-W / W-A (env steps)"]
    head += [f"evaluator {w} s{s} A-W / W-A" for w in ("final", "best") for s in SCENARIO_COLUMNS]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in launches:
        tb = r["train_best"]
        best = "–" if tb is None else (f"{pct(tb.get('success_air_to_water'))} / {pct(tb.get('success_water_to_air'))} "
                                       f"({tb['env_steps'] / 1e6:.2f} M)")
        cells = [str(r["seed"]), f"{'cold' if r['cold'] else 'warm' if r['cold'] is False else '?'} ({num(r['compile_s'])})",
                 num(r["time_to_90_s"]) if r["time_to_90_s"] is not None else "not reached",
                 num(r["env_steps_at_90"], ",d"), num(r["launch_to_end_s"], ".0f"),
                 num(r["env_steps_per_s"] and r["env_steps_per_s"] / 1e6, ".3g"),
                 " / ".join(pct(x) for x in r["train_final"]) if r["train_final"] else "–", best]
        cells += [pair(r[f"eval_{w}"], s) for w in ("final", "best") for s in SCENARIO_COLUMNS]
        lines.append("| " + " | ".join(cells) + " |")
    every_seed = side in ("new", "old")   # every_seed.sh's sides; recipe_end.sh's are the recipes
    recipe = "td3_lstm" if every_seed else side
    apart = ", ".join(f"{k} = {v}" for k, v in (settings or {}).items())
    out = [f"# Every seed, every time: {len(launches)} launches of `python -m docrl_jax.train --config {recipe}`"
           + (f", side {side}" if side == "old" else "") + (f", with {apart}" if apart else "")
           + (f" ({gpu})" if gpu else ""), "", *lines, ""]
    for kind, rows in (("warm", [r for r in launches if r["cold"] is False]),
                       ("cold", [r for r in launches if r["cold"]]), ("all", launches)):
        if not rows:
            continue
        t90 = [r["time_to_90_s"] if r["time_to_90_s"] is not None else float("inf") for r in rows]
        ends = [r["launch_to_end_s"] for r in rows if r["launch_to_end_s"] is not None]
        firsts = [r["first_chunk_s"] for r in rows if r["first_chunk_s"] is not None]
        out.append(f"- {kind} ({len(rows)}): launch to 90 % median {secs(statistics.median(t90))}, slowest "
                   f"{secs(max(t90))}"
                   f" (reached {sum(r['time_to_90_s'] is not None for r in rows)}/{len(rows)}); launch to end median "
                   f"{num(statistics.median(ends) if ends else None, '.0f')} s, "
                   f"slowest {num(max(ends) if ends else None, '.0f')} s; "
                   f"launch to first chunk median {num(statistics.median(firsts) if firsts else None)} s")
    goal = "; ".join(f">= {bar:.0%} both ways in scenario {s}" for s, bar in GOAL)
    for w in ("final", "best"):
        evs = [r[f"eval_{w}"] for r in launches]
        done = [e for e in evs if e is not None]
        if not done:
            continue
        bar = dict(GOAL)
        s2, s13, both = goal_counts(done)
        out.append(f"- evaluator, {w} policies: {s2}/{len(done)} >= {bar[2]:.0%} both ways in scenario 2, "
                   f"{s13}/{len(done)} >= {bar[1]:.0%} / {bar[3]:.0%} both ways in scenarios 1 / 3, "
                   f"{both}/{len(done)} both ({len(launches) - len(done)} not evaluated)")
    footer = f"Run goal: every final policy {goal}; " if every_seed else ""
    if trials:
        footer += f"evaluator {', '.join(map(str, sorted(trials)))} trials per scenario and direction. "
    footer += ("Launch to 90 %: the in-training evaluation of the paper pairs (scenario 2), seconds after the process "
               "started. In-training best: the policy the training evaluation picked and its score on the very episodes "
               "that picked it (optimistic); the evaluator's columns fly it on other episodes.")
    out += ["", footer]
    return "\n".join(out) + "\n"


def paired(launches: list[dict], a: str, b: str) -> str:
    """Seed by seed, side `a` against side `b` over the seeds warm on both: how many `a` reached 90 % sooner
    and the median of `b`'s time minus `a`'s (positive: `a` was sooner; a launch that never reached it
    counts as +inf)."""
    t90 = lambda r: r["time_to_90_s"] if r["time_to_90_s"] is not None else float("inf")  # noqa: E731
    warm = lambda side: {r["seed"]: r for r in launches if r["side"] == side and r["cold"] is False}  # noqa: E731
    sa, sb = warm(a), warm(b)
    seeds = sorted(set(sa) & set(sb))
    if not seeds:
        return ""
    diffs = [t90(sb[s]) - t90(sa[s]) for s in seeds]
    return (f"\nSeed by seed, warm on both sides ({len(seeds)} seeds): {a} reached 90 % sooner than {b} on "
            f"{sum(d > 0 for d in diffs)}; {b} minus {a} (seconds {a} saved): median "
            f"{secs(statistics.median(diffs))}, range {secs(min(diffs))} to {secs(max(diffs))}.\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("source", help="the job's tar (round_every_seed.tar), a folder holding pack/, or pack/")
    ap.add_argument("--out", help="write the table here too (Markdown)")
    args = ap.parse_args(argv)
    if not os.path.exists(args.source):
        ap.exit(2, f"every_seed_table.py: error: {args.source}: no such file or folder (give the job's tar "
                   "or a folder holding pack/)\n")
    with tempfile.TemporaryDirectory(prefix="every_seed_") as tmp:
        work = unpack(args.source, Path(tmp))
        run_dirs = sorted(p for p in (work / "runs").glob("*") if (p / "metrics.csv").is_file())
        if not run_dirs:
            ap.exit(2, f"every_seed_table.py: error: {args.source}: no packed runs (pack/runs_NAME.tgz)\n")
        ends = launch_times(work / "times")
        launches = sorted((launch(work, d, ends) for d in run_dirs), key=lambda r: (r["seed"] is None, r["seed"]))
        cards = (work / "gpu.txt").read_text().splitlines()[1:] if (work / "gpu.txt").is_file() else []
        cards = [c for c in cards if not c.startswith("jax ")]   # nvidia-smi's lines, one per GPU
        gpu = f"{cards[0]} x{len(cards)}" if cards else ""
    sides = sorted({r["side"] for r in launches}, key=lambda x: (x != "new", x))
    # every_seed.sh's two sides: each title names the settings (OLD_ARGS, NEW_ARGS) that set it apart
    apart = {}
    if {"new", "old"} <= set(sides):
        apart = {"new": side_settings(launches, "new", "old"), "old": side_settings(launches, "old", "new")}
    text = "\n".join(table([r for r in launches if r["side"] == side], gpu, side, apart.get(side))
                     for side in sides)
    text += "".join(paired(launches, "new", side) for side in sides if side != "new")
    print(text, end="")
    if args.out:
        Path(args.out).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
