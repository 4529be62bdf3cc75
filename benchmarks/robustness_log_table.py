"""A perturbation table from `python -m docrl_jax.robustness` console logs, for sweeps whose process
did not finish (a device-time limit) and so wrote no robustness.md: success % A-W / W-A per
perturbation setting, the mean over `--scenarios`, the median over `--seeds` policies per method. A
policy counts for a setting only with both directions of every scenario.

    python3 benchmarks/robustness_log_table.py LOG [LOG ...] [--scenarios 1 2] [--seeds 3] [--one-policy-per-log]

A policy is a (method, seed) of the logs; where several logs hold the same one, the first log given
wins. `--one-policy-per-log`: each log is one process with one policy (its "seed 0"), so a policy is
its log.
"""

from __future__ import annotations

import argparse
import re
import statistics
from collections import defaultdict
from pathlib import Path

LINE = re.compile(r"^(.+?) seed (\d+) \| (.+?) \| scenario (\d) (A-W|W-A): (\d+)/(\d+) success")


def table(logs: list[str], scenarios: list[str], seeds: int, one_policy_per_log: bool) -> str:
    rates = defaultdict(lambda: defaultdict(dict))  # (method, setting, direction) -> policy -> {scenario: %}
    owner = {}                                       # (method, seed) -> the log it is taken from
    settings, methods, trials = [], [], set()
    for log in logs:
        for line in Path(log).read_text().splitlines():
            m = LINE.match(line)
            if not m or m.group(4) not in scenarios:
                continue
            method, seed, setting, scenario, direction = m.group(1), m.group(2), m.group(3), m.group(4), m.group(5)
            policy = log if one_policy_per_log else owner.setdefault((method, seed), log)
            if policy != log and not one_policy_per_log:
                continue
            for seen, item in ((settings, setting), (methods, method)):
                if item not in seen:
                    seen.append(item)
            trials.add(int(m.group(7)))
            rates[(method, setting, direction)][(policy, seed)].setdefault(scenario, 100.0 * int(m.group(6)) / int(m.group(7)))
    lines = [f"Success % (A-W / W-A), mean of scenarios {' and '.join(scenarios)}, median over {seeds} seeds; "
             f"{'/'.join(map(str, sorted(trials)))} trials per scenario and direction, the evaluator's trials.", "",
             "| Perturbation | " + " | ".join(methods) + " |", "|---|" + "---|" * len(methods)]
    for setting in settings:
        cells = []
        for method in methods:
            per_dir = []
            for direction in ("A-W", "W-A"):
                done = [statistics.mean(v.values()) for v in rates[(method, setting, direction)].values()
                        if len(v) == len(scenarios)]
                per_dir.append(f"{statistics.median(done):.0f}" if len(done) == seeds else "–")
            cells.append(" / ".join(per_dir))
        lines.append(f"| {setting} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("logs", nargs="+")
    ap.add_argument("--scenarios", nargs="+", default=["1", "2"])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--one-policy-per-log", action="store_true")
    args = ap.parse_args()
    print(table(args.logs, args.scenarios, args.seeds, args.one_policy_per_log))
