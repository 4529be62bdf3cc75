import sys, time
sys.path.insert(0, "tests/train")
from _trainer_common import EASY
from docrl_jax.config import config_from_dict
from docrl_jax.train.programs import compile_programs
raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in EASY.items()}
raw["env"].update({"scenario": 0, "layout_boxes": [0, 1], "layout_capsules": [0, 1], "layout_beam_fraction": 0.0,
                   "dr_motor_tau_scale": [1.0, 2.0], "dr_thrust_air_scale": [0.9, 1.1], "dr_obs_latency": [0, 1]})
if len(sys.argv) > 1: raw["env"]["substep_unroll"] = int(sys.argv[1])
t0 = time.time()
compile_programs(config_from_dict(raw))
print("unroll", sys.argv[1:], time.time() - t0)
