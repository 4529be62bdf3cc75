"""One report and one figure for four methods of this round: each launch's GPU evaluation (paper pairs
of scenarios 1-3, random trips, held-out layouts) with its CPU perturbations (scenarios 1-2 and 3, 50
trials; their nominal rows are left out, the GPU's stand for them), relabelled.
    python combine.py   # writes combined/robustness.{md,png}"""
import json
import sys
from pathlib import Path

from docrl_jax.evaluate import robustness_report as report
from docrl_jax.evaluate.robustness import PERTURBATIONS

here = Path(__file__).parent
LABELS = {"sac_mlp_gen_s10": "sac_mlp_generalist", "gen_s13": "td3_lstm_generalist",
          "sac_lstm_gen_s10": "sac_lstm, the generalist's way", "td3_lstm_s0": "td3_lstm (default)"}
rows, meta = [], None
for name, label in LABELS.items():
    gpu = json.loads((here / "eval" / name / "robustness.json").read_text())
    meta = meta or gpu["meta"]
    cpu = []
    for folder in (f"perturbations_{name}", f"perturbations_s3_{name}"):
        path = here / "eval" / folder / "robustness.json"
        if path.exists():
            cpu += json.loads(path.read_text())["rows"]
        else:
            print(f"{folder}: not run yet", file=sys.stderr)
    for r in gpu["rows"] + [r for r in cpu if r["perturbation"] != "nominal"]:
        rows.append({**r, "method": label})
out = here / "combined"
out.mkdir(exist_ok=True)
(out / "robustness.md").write_text(report.markdown(rows, meta, PERTURBATIONS))
report.plot(rows, out / "robustness.png", PERTURBATIONS, title="Four recipes, 3 seeds each, trained side by side on one 4-GPU H200 machine")
print(f"wrote {out}/robustness.md, robustness.png")
