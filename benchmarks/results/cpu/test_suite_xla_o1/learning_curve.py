import csv, sys, time
sys.path.insert(0, "tests/train")
from _trainer_common import EASY
from docrl_jax.config import config_from_dict
from docrl_jax.train.run import run
raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in EASY.items()}
raw["env"].update({"scenario": 0, "layout_boxes": [0, 1], "layout_capsules": [0, 1], "layout_beam_fraction": 0.0,
                   "dr_motor_tau_scale": [1.0, 2.0], "dr_thrust_air_scale": [0.9, 1.1], "dr_obs_latency": [0, 1]})
raw["train"].update({"total_env_steps": 160000, "eval_every": 16000, "checkpoint_every": 160000,
                     "seed": int(sys.argv[1])})
t0 = time.time()
run(config_from_dict(raw), f"/tmp/curve{sys.argv[1]}", show_progress=False)
print(time.time() - t0)
for r in csv.DictReader(open(f"/tmp/curve{sys.argv[1]}/metrics.csv")):
    print(r["env_steps"], r["success_rate"], r["wall_time_s"])
