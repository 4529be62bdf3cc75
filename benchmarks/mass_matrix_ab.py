"""MJX's dense against its sparse mass-matrix factorisation on this env, one process per side.

    for m in dense sparse dense sparse; do python3 benchmarks/mass_matrix_ab.py $m; done   # (GPU machine)

The side (`dense` or `sparse`) is set on every model the process loads (mujoco.MjModel.opt.jacobian;
the scenes' own setting is assets/common.xml's); the rest is the package as it is. Measures, in turn:
the env alone (scenario 2, 4,096 envs, no auto-reset, 100 control steps of random actions per jitted
scan, median of 5 calls after a warm-up) and the default td3_lstm's training chunk at 4,096 envs
(50 iterations, every one learning: train.start_steps=0, 128 steps of history per env; median of 5 chunks
after a warm-up, `common.time_chunks`). Appends one JSON line per process to $OUT/sparse_ab.jsonl.
"""
import json
import os
import statistics
import sys
import time

import mujoco

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
mode = sys.argv[1]
_from_xml_path = mujoco.MjModel.from_xml_path


def _with_side(path, *args, **kwargs):
    m = _from_xml_path(path, *args, **kwargs)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_SPARSE if mode == "sparse" else mujoco.mjtJacobian.mjJAC_DENSE
    return m


mujoco.MjModel.from_xml_path = _with_side
import jax  # noqa: E402

import docrl_jax.envs as envs  # noqa: E402
from common import time_chunks  # noqa: E402
from docrl_jax.config import load_config  # noqa: E402
from docrl_jax.train import make_trainer  # noqa: E402

out = os.environ.get("OUT", "/tmp/out")
n, iters = 4096, 50
env = envs.make(2)
st = jax.vmap(env.reset)(jax.random.split(jax.random.PRNGKey(0), n))


def roll(s, key):
    def body(s, k):
        return jax.vmap(env.step)(s, jax.random.uniform(k, (n, 3), minval=-1, maxval=1)), None
    return jax.lax.scan(body, s, jax.random.split(key, 100))[0]


r = jax.jit(roll).lower(st, jax.random.PRNGKey(1)).compile()
st = r(st, jax.random.PRNGKey(1))
jax.block_until_ready(st)
ts = []
for i in range(5):
    t0 = time.perf_counter()
    st = r(st, jax.random.PRNGKey(i + 2))
    jax.block_until_ready(st)
    ts.append(time.perf_counter() - t0)
env_sps = n * 100 / statistics.median(ts)
sets = [f"env.num_envs={n}", f"train.log_every={n * iters}", "train.start_steps=0", "train.num_seeds=1",
        f"replay.buffer_size={128 * n}"]
config = load_config("td3_lstm", sets)
trainer = make_trainer(config)
state = jax.jit(trainer.init)(jax.random.PRNGKey(0))
t0 = time.perf_counter()
chunk = jax.jit(trainer.chunk, donate_argnums=0).lower(state).compile()
compile_s = time.perf_counter() - t0
state, times, learn = time_chunks(chunk, state, 5)
med = statistics.median(times)
row = {"mode": mode, "env_steps_per_s_env_alone": round(env_sps), "env_times": ts, "chunk_compile_s": round(compile_s, 1),
       "chunk_s": times, "learner_env_steps_per_s": round(trainer.steps_per_chunk / med), "learn": learn}
print(json.dumps(row), flush=True)
with open(f"{out}/sparse_ab.jsonl", "a") as f:
    f.write(json.dumps(row) + "\n")
