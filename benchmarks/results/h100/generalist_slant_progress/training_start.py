"""When each seed starts to learn: the env steps (M) at which its training success first passes 0.3,
and its final training success, from runs' metrics.csv.
    python training_start.py runs/* ../generalist_collide_penalty/runs/gen_rc100_s10 ../generalist_slant_beams/runs/gen_slant8e30_s1[03] > training_start.txt"""
import csv, sys

for run in sys.argv[1:]:
    rows = list(csv.DictReader(open(f"{run}/metrics.csv")))
    for seed in sorted({r["seed"] for r in rows}, key=int):
        rs = [r for r in rows if r["seed"] == seed and r["train_success_rate"] not in ("", "nan")]
        first = next((int(r["env_steps"]) / 1e6 for r in rs if float(r["train_success_rate"]) > 0.3), None)
        print(f"{run}: seed {seed} passes 0.3 at {first} M env steps; final {float(rs[-1]['train_success_rate']):.2f}")
