"""The peer table and figure: our trainers (benchmarks/time_to_success.py results) against Brax's
(benchmarks/peers.py results), launch to 90 % in both directions of the paper's scenario-2 pairs.

    python benchmarks/peer_table.py --ours R/time_to_success_td3_lstm.json R/time_to_success_sac_lstm.json \
        --peers R/peers_sac_*.json R/peers_ppo_*.json --out R

Reads the JSON the two scripts write and groups the runs by trainer and configuration: runs with the
same settings from several peers.py files (e.g. seeds split over GPUs) are one group, and a Brax group
is named by its recipe (peers.py's `recipe`; files written before recipes existed used Brax's Ant
recipes) and the settings that differ from it. Writes
`peer_table.md`, one row per group (each seed's time, the median, the median's ratio to the first
--ours group's, each seed's best and final evaluation, env steps/s and updates/s), and
`peer_success_vs_time.png` (the weaker direction's success against seconds since launch; every run a
line, every group a colour).

Times are launch (process start, compilation included) to the end of the first evaluation with both
directions >= the target, as each script measured it. For Brax's trainers that includes our
evaluation of their policy (its first call compiles, ~20 s on an H200), so the table also gives their
time without it; our trainers' own periodic evaluation is part of their run, as a user gets it. A
group's median counts a run that did not reach the target as infinitely slow. Our curves are on the
trainer's clock (`wall_time_s` in metrics.csv) plus the launch offset time_to_success measured.

Env steps/s and gradient updates/s run from a run's first evaluation to its last (compilation left
out; the trainer's own evaluations included, ours of Brax's policies left out). An update is one
optimiser step on each trainer's own batch: 1,024 sequences of 8 trained steps for ours, 2,048
transitions for Brax SAC, a minibatch of batch_size x unroll_length steps for Brax PPO.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics

from docrl_jax.benchmarking import DEFAULT_PEER_RECIPE, peer_recipe


def our_groups(paths: list[str]) -> dict[str, list[dict]]:
    groups = {}
    for path in paths:
        with open(path) as f:
            d = json.load(f)
        label = f"ours: {d['config']}" + (f" ({' '.join(d['overrides'])})" if d.get("overrides") else "")
        runs = []
        for s in d["seeds"]:
            curve = [c for c in s["curve"] if c.get("success_air_to_water") not in (None, "")]
            if s["reached"]:
                offset = s["time_to_target_s"] - s["trainer_wall_at_target_s"]
            else:   # first_eval_s: launch to the first evaluation after step 0 (curve[1])
                offset = s["first_eval_s"] - float(curve[1]["wall_time_s"]) if len(curve) > 1 else 0.0
            trained = curve[1:]   # from the first evaluation after step 0 to the last
            span = float(trained[-1]["wall_time_s"]) - float(trained[0]["wall_time_s"]) if len(trained) > 1 else 0.0
            rates = ((float(trained[-1]["env_steps"]) - float(trained[0]["env_steps"])) / span,
                     (float(trained[-1]["grad_updates"]) - float(trained[0]["grad_updates"])) / span) if span else None
            runs.append({"seed": s["seed"], "reached": s["reached"], "time": s["time_to_target_s"], "time_excl": None,
                         "rates": rates,
                         "best": (s["best_success"]["air_to_water"], s["best_success"]["water_to_air"]),
                         "final": (s["final"]["air_to_water"], s["final"]["water_to_air"]),
                         "stop": "ended" if s["stop_reason"].startswith("trainer exited (0)") else s["stop_reason"],
                         "elapsed": s["elapsed_s"],
                         "curve": [(float(c["wall_time_s"]) + offset,
                                    min(float(c["success_air_to_water"]), float(c["success_water_to_air"])))
                                   for c in curve]})
        groups.setdefault(label, []).extend(runs)
    return groups


def peer_groups(paths: list[str]) -> dict[str, list[dict]]:
    groups = {}
    for path in paths:
        with open(path) as f:
            d = json.load(f)
        for r in d["runs"]:
            final = r["final"] or {}
            name = r.get("recipe", DEFAULT_PEER_RECIPE)
            published = peer_recipe(name, r["trainer"])[0]
            changed = {k: v for k, v in r["config"].items() if published.get(k) != v}
            parts = ([] if name == DEFAULT_PEER_RECIPE else [f"{name} recipe"]) + [f"{k}={v}" for k, v in changed.items()]
            label = f"Brax {r['trainer']} (" + ("; ".join(parts) if parts else "Brax's defaults") + ")"
            groups.setdefault(label, []).append({
                "seed": r["seed"], "reached": r["reached"], "time": r.get("time_to_target_s"),
                "time_excl": r.get("time_to_target_excl_eval_s"),
                "best": (r["best"]["air_to_water"], r["best"]["water_to_air"]),
                "final": (final.get("air_to_water"), final.get("water_to_air")),
                "stop": r.get("stop_reason"), "elapsed": r.get("elapsed_s"),
                "rates": brax_rates(r),
                "curve": [(e["wall_s"], min(e["air_to_water"], e["water_to_air"])) for e in r["evals"]]})
    return groups


def brax_rates(r: dict) -> tuple[float, float] | None:
    """(env steps/s, gradient updates/s) of a Brax run from its first to its last evaluation, our
    evaluations' time left out (Brax's own evaluations stay in: the trainer runs them). Updates are
    counted from Brax's schedule: SAC does grad_updates_per_step per vectorised env step; PPO does
    num_minibatches * num_updates_per_batch per batch_size * num_minibatches * unroll_length env steps."""
    ev, c = r["evals"], r["config"]
    if len(ev) < 2:
        return None
    span = ev[-1]["wall_s"] - ev[0]["wall_s"] - sum(e["eval_s"] for e in ev[1:])
    steps = ev[-1]["env_steps"] - ev[0]["env_steps"]
    if r["trainer"] == "sac":
        updates = steps / (c["num_envs"] * c["action_repeat"]) * c["grad_updates_per_step"]
    else:
        updates = (steps / (c["batch_size"] * c["num_minibatches"] * c["unroll_length"] * c["action_repeat"])
                   * c["num_minibatches"] * c["num_updates_per_batch"])
    return steps / span, updates / span


def median_time(runs: list[dict]) -> float:
    return statistics.median([r["time"] if r["reached"] else math.inf for r in runs])


def table(groups: dict[str, list[dict]], reference: str, target: float) -> str:
    ref = median_time(groups[reference])
    lines = [f"| trainer / configuration | seeds | time to {target:.0%} both ways, per seed (s) | median (s) | "
             f"median / {reference}'s | without our evaluations, per seed (s) | best A-W / W-A per seed | "
             "final A-W / W-A per seed | env steps/s (median) | gradient updates/s (median) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for label, runs in groups.items():
        runs = sorted(runs, key=lambda r: r["seed"])
        per_seed = ", ".join(f"{r['time']:.1f}" if r["reached"] else
                             f"no ({r['stop']} at {r['elapsed']:.0f})" for r in runs)
        excl = ", ".join("–" if r["time_excl"] is None else f"{r['time_excl']:.1f}" for r in runs)
        med = median_time(runs)
        ratio = "–" if label == reference else (f"{med / ref:.2f}×" if math.isfinite(med) else "–")
        fmt = lambda p: " / ".join("–" if v is None else f"{v:.2f}" for v in p)
        cells = [label, ", ".join(str(r["seed"]) for r in runs), per_seed,
                 f"{med:.1f}" if math.isfinite(med) else "not reached", ratio, excl,
                 "; ".join(fmt(r["best"]) for r in runs), "; ".join(fmt(r["final"]) for r in runs)]
        rates = [r["rates"] for r in runs if r["rates"]]
        cells += [f"{statistics.median(x[i] for x in rates):,.0f}" if rates else "–" for i in (0, 1)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def figure(groups: dict[str, list[dict]], target: float, path: str, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import textwrap
    fig, ax = plt.subplots(figsize=(8, 6.5))
    for i, (label, runs) in enumerate(groups.items()):
        colour = f"C{i}"
        for j, r in enumerate(sorted(runs, key=lambda r: r["seed"])):
            xs, ys = zip(*r["curve"]) if r["curve"] else ((), ())
            ax.plot(xs, ys, color=colour, marker=".", lw=1.2, alpha=0.85,
                    label=textwrap.fill(label, 90) if j == 0 else None)
            if r["reached"]:
                ax.plot([r["time"]], [target], color=colour, marker="o", ms=7, mfc="none")
    ax.axhline(target, color="grey", ls="--", lw=0.8)
    ax.set_xlabel("seconds since launch (compilation included)")
    ax.set_ylabel("success, weaker direction (A-W, W-A)")
    ax.set_ylim(-0.02, 1.02)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ours", nargs="+", required=True, help="time_to_success_*.json; the first is the reference")
    ap.add_argument("--peers", nargs="+", default=[], help="peers_*.json")
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--title", default="Our trainers and Brax's on the HUAUV env, paper reward, scenario-2 pairs")
    ap.add_argument("--out", required=True)
    args = ap.parse_args(argv)
    groups = {**our_groups(args.ours), **peer_groups(args.peers)}
    reference = next(iter(our_groups(args.ours[:1])))
    os.makedirs(args.out, exist_ok=True)
    md = table(groups, reference, args.target)
    with open(os.path.join(args.out, "peer_table.md"), "w") as f:
        f.write(f"# Launch to {args.target:.0%} in both directions\n\nCommand: `python benchmarks/peer_table.py "
                f"--ours {' '.join(args.ours)} --peers {' '.join(args.peers)} --out {args.out}`\n\n" + md)
    figure(groups, args.target, os.path.join(args.out, "peer_success_vs_time.png"), args.title)
    print(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
