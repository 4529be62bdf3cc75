"""Builds table.md from the robustness logs here: gpu_h200.log (one process for all nine policies on
an H200, stopped by its 560 s limit during sac_mlp's seed 1) and cpu_sac_mlp_seeds12.log (sac_mlp's
seeds 1 and 2 again, on the 2-core CPU machine). A (method, seed, setting) counts only with both
directions of both scenarios, and for sac_mlp seeds 1 and 2 the CPU rerun replaces the GPU lines; README.md has the commands.
    python table_from_logs.py > table.md"""
import re
import statistics
from collections import defaultdict
from pathlib import Path

LINE = re.compile(r"^(.+?) seed (\d+) \| (.+?) \| scenario ([12]) (A-W|W-A): (\d+)/(\d+) success")
rates = defaultdict(dict)          # (method, seed, setting, direction) -> {scenario: success %}
order, methods = [], []
for log in ("cpu_sac_mlp_seeds12.log", "gpu_h200.log"):  # the CPU rerun first: its seeds win
    for line in (Path(__file__).parent / log).read_text().splitlines():
        m = LINE.match(line)
        if not m:
            continue
        method, seed, setting, scenario, direction = m.group(1), int(m.group(2)), m.group(3), m.group(4), m.group(5)
        for seen, item in ((order, setting), (methods, method)):
            if item not in seen:
                seen.append(item)
        rates[(method, seed, setting, direction)].setdefault(scenario, 100.0 * int(m.group(6)) / int(m.group(7)))
print("Success % (A-W / W-A), mean of scenarios 1 and 2, median over 3 seeds; 50 trials per scenario and "
      "direction, the evaluator's trials.\n")
print("| Perturbation | " + " | ".join(methods) + " |")
print("|---|" + "---|" * len(methods))
for setting in order:
    cells = []
    for method in methods:
        per_dir = []
        for direction in ("A-W", "W-A"):
            seeds = [statistics.mean(v.values()) for (me, _, s, d), v in rates.items()
                     if me == method and s == setting and d == direction and len(v) == 2]
            per_dir.append(f"{statistics.median(seeds):.0f}" if len(seeds) == 3 else "–")
        cells.append(" / ".join(per_dir))
    print(f"| {setting} | " + " | ".join(cells) + " |")
