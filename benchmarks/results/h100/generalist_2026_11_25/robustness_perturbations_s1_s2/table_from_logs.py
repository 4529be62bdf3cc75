"""Builds table.md from the six robustness logs here (one process per policy, killed at 520 s after
scenarios 1 and 2 of the perturbation sweep had finished for all six: see ../README.md).
    python table_from_logs.py > table.md"""
import re
import statistics
from collections import defaultdict
from pathlib import Path

LINE = re.compile(r"^(\S+) seed \d+ \| (.+?) \| scenario (\d) (A-W|W-A): (\d+)/(\d+) success, (\d+) collisions, "
                  r"(\d+) out of bounds, (\d+) time-outs")
rates = defaultdict(list)          # (method, setting, direction, log) -> success % per scenario
order = []
for log in sorted(Path(__file__).parent.glob("r*.log")):
    for line in log.read_text().splitlines():
        m = LINE.match(line)
        if not m or m.group(3) not in ("1", "2"):
            continue
        method, setting, direction = m.group(1), m.group(2), m.group(4)
        if setting not in order:
            order.append(setting)
        rates[(method, setting, direction, log.name)].append(100.0 * int(m.group(5)) / int(m.group(6)))
methods = ["td3_lstm_generalist", "td3_lstm"]
print("Success % (A-W / W-A), mean of scenarios 1 and 2, median over 3 seeds; 100 trials per scenario and "
      "direction, the evaluator's trials.\n")
print("| Perturbation | " + " | ".join(methods) + " |")
print("|---|" + "---|" * len(methods))
for setting in order:
    cells = []
    for method in methods:
        per_dir = []
        for direction in ("A-W", "W-A"):
            seeds = [statistics.mean(v) for (me, s, d, _), v in rates.items()
                     if me == method and s == setting and d == direction and len(v) == 2]
            per_dir.append(f"{statistics.median(seeds):.0f}" if len(seeds) == 3 else "–")
        cells.append(" / ".join(per_dir))
    print(f"| {setting} | " + " | ".join(cells) + " |")
