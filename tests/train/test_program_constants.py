"""Programs whose constants JAX passes as hidden arguments (`jax_use_simplified_jaxpr_constants`, in JAX
0.10 and 0.11, off by default; under it an env program closes over dozens to hundreds: the MJX model,
the scene's solids). The program store keeps those constants with the executable, so a loaded program
runs and computes what the compiled one does; an entry whose executable expects other inputs than the
entry carries is a miss, never a program that fails at its first call ("compiled for N inputs but
called with M")."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.experimental import serialize_executable

from docrl_jax.train import program_store

from _trainer_common import rewrite_entry

# Run under hoisting (a fresh process: JAX reads the setting when it is imported). Prints one JSON line.
HOISTED = r"""
import json, sys
from pathlib import Path
import jax, jax.numpy as jnp, numpy as np
from docrl_jax.train import program_store, programs
sys.path.insert(0, sys.argv[2])
from _trainer_common import easy_config, rewrite_entry

store, devices, out = Path(sys.argv[1]), (jax.devices()[0],), {}
table, ramp = np.arange(100.0, dtype=np.float32), jnp.linspace(0.0, 1.0, 50)
small = jax.jit(lambda x, y: (x * table, y + ramp[:10])).lower(np.ones(100, np.float32), np.ones(10, np.float32)).compile()
out["small_consts"] = len(small._params.const_args)
out["small_saved"] = program_store.save(store, "small", small)
args = (np.full(100, 0.5, np.float32), np.full(10, 2.0, np.float32))
loaded = program_store.load(store, "small", devices)
out["small_equal"] = loaded is not None and all(np.array_equal(a, b) for a, b in zip(small(*args), loaded(*args)))
# The entry of the failure this guards against: the executable expects its constants, the entry has none.
rewrite_entry(store / "small.bin", lambda consts: [])
out["stripped_loads"] = program_store.load(store, "small", devices) is not None

# The trainer's evaluation (the program that failed), at a tiny size.
config = programs.program_config(easy_config(env__num_envs=4, train__eval_episodes=4))
init, _, evaluate, _ = programs.jitted_programs(config, devices, False)
keys = jax.ShapeDtypeStruct((1, 2), jnp.uint32)
state = jax.eval_shape(init, keys, jax.ShapeDtypeStruct((), jnp.int32))
compiled = evaluate.lower(state.agent.actor_average, keys).compile()
out["eval_consts"] = len(compiled._params.const_args)
out["eval_saved"] = program_store.save(store, "evaluate", compiled)
loaded = program_store.load(store, "evaluate", devices)
params = jax.tree.map(lambda s: jnp.full(s.shape, 0.01, s.dtype), state.agent.actor_average)
key = jnp.stack([jax.random.PRNGKey(3)])
if loaded is not None:
    a, b = jax.device_get(compiled(params, key)), jax.device_get(loaded(params, key))
    out["eval_keys"] = sorted(a)
    out["eval_equal"] = all(np.array_equal(a[k], b[k], equal_nan=True) for k in a)
print(json.dumps(out))
"""


# Run in a fresh process (the env imports some modules only while a program is traced). Prints one JSON
# line: per program, its jaxpr's inputs and the arguments a call passes.
INPUTS = r"""
import json
import jax, jax.numpy as jnp
from docrl_jax.config import load_config
from docrl_jax.train import programs
config = programs.program_config(load_config("sac_mlp_tanks", ["env.num_envs=4", "levels.capacity=8",
    "levels.refresh=4", "replay.batch_size=8", "train.eval_episodes=2", "replay.buffer_size=64"]))
init, chunk, evaluate, _ = programs.jitted_programs(config, (jax.devices()[0],), False)
keys, total = jax.ShapeDtypeStruct((1, 2), jnp.uint32), jax.ShapeDtypeStruct((), jnp.int32)
state = jax.eval_shape(init, keys, total)
out = {}
for name, f, args in [("init", init, (keys, total)), ("chunk", chunk, (state,)),
                      ("evaluate", evaluate, (state.agent.actor_average, keys))]:
    out[name] = [len(f.trace(*args).jaxpr.jaxpr.invars), len(jax.tree.leaves(args))]
print(json.dumps(out))
"""


def test_hoisted_constants_are_stored_and_loaded_with_the_program(tmp_path):
    here = Path(__file__).resolve().parent
    env = {**os.environ, "JAX_USE_SIMPLIFIED_JAXPR_CONSTANTS": "true", "JAX_PLATFORMS": "cpu"}
    done = subprocess.run([sys.executable, "-c", HOISTED, str(tmp_path), str(here)], env=env, cwd=here,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    if out["small_consts"] == 0:
        pytest.skip(f"JAX {jax.__version__} passes no constants as arguments")
    assert out["small_consts"] == 2 and out["small_saved"] and out["small_equal"]
    assert not out["stripped_loads"]
    assert out["eval_consts"] > 0 and out["eval_saved"]
    assert out["eval_keys"] and out["eval_equal"]


def test_an_entry_whose_inputs_differ_from_its_executable_is_a_miss(tmp_path):
    """Under the default settings: a program with no hidden constants loads with none; the same
    executable stored with a constant it does not take is a miss (whichever way the counts differ)."""
    devices = (jax.devices()[0],)
    f = jax.jit(lambda x: jnp.cos(x) + 1.0).lower(jnp.ones(4)).compile()
    assert program_store.save(tmp_path, "f", f)
    loaded = program_store.load(tmp_path, "f", devices)
    assert loaded is not None and len(loaded._params.const_args) == len(f._params.const_args)
    np.testing.assert_array_equal(loaded(jnp.arange(4.0)), f(jnp.arange(4.0)))
    rewrite_entry(tmp_path / "f.bin", lambda consts: [*consts, np.zeros(3, np.float32)])
    assert program_store.load(tmp_path, "f", devices) is None


def test_a_serialised_executable_outside_the_store_format_is_a_miss(tmp_path):
    """JAX's own serialisation (no constants slot) under the store's name: a miss, not a crash."""
    f = jax.jit(lambda x: x * 3.0).lower(jnp.ones(2)).compile()
    payload, in_tree, out_tree = serialize_executable.serialize(f)
    (tmp_path / "g.bin").write_bytes(pickle.dumps((program_store.FORMAT, payload, pickle.dumps((in_tree, out_tree)))))
    assert program_store.load(tmp_path, "g", (jax.devices()[0],)) is None


def test_the_trainer_programs_take_only_their_arguments():
    """A structured-tanks run's programs, traced in a fresh process as a launch traces them: each one's
    inputs are its arguments. A jnp array made at import of a module the env first imports while
    tracing is a tracer of that trace; every later program closing over it gets all its constants as
    inputs that no call passes ("compiled for 568 inputs but called with 9")."""
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    env.pop("JAX_USE_SIMPLIFIED_JAXPR_CONSTANTS", None)
    done = subprocess.run([sys.executable, "-c", INPUTS], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(out) == {"init", "chunk", "evaluate"}
    assert all(inputs == args for inputs, args in out.values()), out

