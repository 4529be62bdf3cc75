"""The table of benchmarks/ab_launches.sh (or any DIR/{old,new,...}/time_to_success_{side}_s*.json with
the runs in DIR/runs_{side}/): per launch, start-up (startup.json), the median env steps/s of the
learning chunks (from the trainer's log), seconds between evaluation rows after the first (the
steady-state pace), time to 90 % both ways, and, for launches run to their end (--to-end), launch to
end and the final evaluation's A-W / W-A; medians per version.

    python3 benchmarks/ab_summary.py benchmarks/results/h100/top_floor_rebuild > .../summary.md
"""

from __future__ import annotations

import csv
import glob
import json
import os
import statistics
import sys

from docrl_jax.benchmarking import chunk_steps_per_s


def launch(run_dir: str, ttt: dict, log: str) -> dict:
    rows = list(csv.DictReader(open(os.path.join(run_dir, "metrics.csv"))))
    wall = [float(r["wall_time_s"]) for r in rows]
    start = json.load(open(os.path.join(run_dir, "startup.json")))
    seed = ttt["seeds"][0]
    return {"launch": os.path.basename(run_dir), "compile_s": start["compile_s"],
            "launch_to_first_chunk_s": start["launch_to_first_chunk_s"],
            "chunk_steps_per_s": chunk_steps_per_s(log),
            "interval_s": statistics.median([b - a for a, b in zip(wall[1:-1], wall[2:])]),
            "time_to_90_s": seed["time_to_target_s"], "env_steps_at_90": seed["env_steps_at_target"],
            "launch_to_end_s": seed["elapsed_s"] if ttt.get("to_end") else None,
            "final_aw": seed["final"]["air_to_water"] if ttt.get("to_end") else None,
            "final_wa": seed["final"]["water_to_air"] if ttt.get("to_end") else None}


def main(dirs: list[str]) -> None:
    """Every side found (DIR/SIDE/time_to_success_SIDE_s*.json: old and new, or the SIDES of
    ab_launches.sh), old first."""
    sides = sorted({os.path.basename(os.path.dirname(p)) for d in dirs
                    for p in glob.glob(os.path.join(d, "*", "time_to_success_*_s*.json"))},
                   key=lambda s: (s != "old", s != "new", s))
    by_side: dict[str, list[dict]] = {s: [] for s in sides}
    for d in dirs:
        for side in by_side:
            for path in sorted(glob.glob(os.path.join(d, side, f"time_to_success_{side}_s*.json"))):
                ttt = json.load(open(path))
                run = os.path.join(d, f"runs_{side}", os.path.basename(ttt["seeds"][0]["run_dir"]))
                by_side[side].append(launch(run, ttt, path.replace(".json", f"_seed{ttt['seeds'][0]['seed']}.log")))
    cols = ["launch", "compile_s", "launch_to_first_chunk_s", "chunk_steps_per_s", "interval_s", "time_to_90_s",
            "env_steps_at_90", "launch_to_end_s", "final_aw", "final_wa"]
    cols = [c for c in cols if any(r[c] is not None for rows in by_side.values() for r in rows)]
    print("| " + " | ".join(cols) + " |\n|" + "---|" * len(cols))
    for side, rows in by_side.items():
        for r in rows:
            print("| " + " | ".join(str(round(r[c], 2) if isinstance(r[c], float) else r[c]) for c in cols) + " |")
        med = {c: statistics.median([r[c] for r in rows if r[c] is not None]) for c in cols[1:]}
        print(f"| **{side}: median of {len(rows)}** | " + " | ".join(f"{med[c]:.2f}" for c in cols[1:]) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
