"""MJX's dense against its sparse mass-matrix factorisation on this env, one process per side.

    for m in dense sparse dense sparse; do python3 benchmarks/mass_matrix_ab.py $m; done   # (GPU machine)

The side (`dense` or `sparse`) is set on every model the process loads (mujoco.MjModel.opt.jacobian;
the scenes' own setting is assets/common.xml's); the rest is the package as it is. Measures, in turn:
the env alone (`docrl_jax.benchmarking.env_throughput`: scenario 2, no auto-reset, 100 control steps of random actions
per jitted scan, median of 5 calls after a warm-up) and the default td3_lstm's training chunk
(`docrl_jax.benchmarking.train_throughput`: 50 iterations, every one learning, median of 5 chunks after a warm-up), both
at `--num-envs` (4,096). Appends one JSON line per process to $OUT/sparse_ab.jsonl.
"""
import argparse
import json
import os

import mujoco


parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("mode", choices=("dense", "sparse"))
parser.add_argument("--num-envs", type=int, default=4096)
args = parser.parse_args()
_from_xml_path = mujoco.MjModel.from_xml_path


def _with_side(path, *a, **kw):
    m = _from_xml_path(path, *a, **kw)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE if args.mode == "sparse" else mujoco.mjtJacobian.mjJAC_DENSE
    return m


mujoco.MjModel.from_xml_path = _with_side   # before the env modules load any model
from docrl_jax.benchmarking import env_throughput, train_throughput  # noqa: E402

env = env_throughput(2, args.num_envs, 100, 5, "plain")
chunk = train_throughput("td3_lstm", args.num_envs, 50, 5, [])
row = {"mode": args.mode, "env_steps_per_s_env_alone": env["control_steps_per_s"], "env_times": env["call_s_all"],
       "chunk_compile_s": chunk["compile_s"], "chunk_s": chunk["chunk_s_all"],
       "learner_env_steps_per_s": chunk["env_steps_per_s"], "learn": chunk["learning_iters_per_chunk"]}
print(json.dumps(row), flush=True)
out = os.environ.get("OUT", "/tmp/out")
with open(f"{out}/sparse_ab.jsonl", "a") as f:
    f.write(json.dumps(row) + "\n")
