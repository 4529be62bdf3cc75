"""Per-seed success (%) from robustness.csv files: the median over seeds and each seed, per test,
perturbation, magnitude and direction (scenarios averaged per seed, as robustness.md does), with the
collisions and time-outs summed over scenarios.
    python per_seed.py eval/slant8e30_prog2_s*/robustness.csv"""
import collections, csv, statistics, sys

cells = collections.defaultdict(lambda: collections.defaultdict(list))
counts = collections.defaultdict(lambda: collections.defaultdict(lambda: [0, 0]))
for path in sys.argv[1:]:
    for r in csv.DictReader(open(path)):
        key = (r["test"], r["perturbation"], r["magnitude"], r["direction"])
        seed = (path, r["method"], r["seed_index"])
        cells[key][seed].append(100 * int(r["successes"]) / int(r["trials"]))
        counts[key][seed][0] += int(r["collisions"])
        counts[key][seed][1] += int(r["timeouts"])
for key, seeds in cells.items():
    means = [statistics.mean(v) for v in seeds.values()]
    print(" ".join(k for k in key if k), f"| median {statistics.median(means):.1f} | seeds",
          " ".join(f"{m:.1f}" for m in means), "| collisions, time-outs", [tuple(c) for c in counts[key].values()])
