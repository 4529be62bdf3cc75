"""The actor as one pure step function, and the three files it is written as:

    ONNX       policy.onnx          jax2onnx; run with onnxruntime (named inputs and outputs)
    StableHLO  policy.stablehlo     jax.export's serialised artefact; reloaded with jax alone
    NumPy      policy_weights.npz   Flax's parameter names, + numpy_policy.py (standalone loader)

The step function is (observation, c, h) -> (action, c_out, h_out) for an LSTM actor with memory and
observation -> action otherwise; its batch dimension is symbolic ("B") in ONNX and StableHLO. It is
the agent's own deterministic `act` (TD3/DDPG: the tanh output; SAC: tanh of the mean), so an export
acts exactly as `docrl_jax.runs.load_policy` does.
"""

from __future__ import annotations

import contextlib
import importlib.util
import logging
import shutil
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

from docrl_jax.config import Config, observation_size
from docrl_jax.export.manifest import BATCH, io_names

ONNX_FILE = "policy.onnx"
STABLEHLO_FILE = "policy.stablehlo"
WEIGHTS_FILE = "policy_weights.npz"
LOADER_FILE = "numpy_policy.py"
MANIFEST_FILE = "policy.json"
FORMATS = ("onnx", "stablehlo", "numpy")
EXPORT_FILES = (MANIFEST_FILE, ONNX_FILE, STABLEHLO_FILE, WEIGHTS_FILE, LOADER_FILE)   # everything an export writes
DEFAULT_OPSET = 17          # onnxruntime >= 1.13 runs it; jax2onnx 0.12.5 converts the actors down to opset 13
ONNX_PACKAGES = ("jax2onnx", "onnx")
INSTALL_HINT = "pip install -e '.[export]'"


def missing_onnx_packages() -> list[str]:
    """The packages the ONNX artefact needs that are not installed (checked without importing them)."""
    return [name for name in ONNX_PACKAGES if importlib.util.find_spec(name) is None]


def step_function(config: Config, params) -> Callable:
    """The deterministic step of the actor with `params` (one seed's actor params)."""
    from docrl_jax.algorithms import make_agent
    agent = make_agent(config)

    if config.agent.recurrent:
        def step(observation, c, h):
            (c, h), action = agent.act(params, (c, h), observation)
            return action, c, h
    else:
        def step(observation):   # a zero carry on every call, as Policy.act does
            return agent.act(params, agent.actor.init_carry(()), observation)[1]
    return step


def input_shapes(config: Config, batch: Any = BATCH) -> list[tuple]:
    units = config.agent.actor_hidden[0]
    return [(batch, observation_size(config))] + ([(batch, units)] * 2 if config.agent.recurrent else [])


@contextlib.contextmanager
def _quiet_jax2onnx():
    """jax2onnx logs warnings with tracebacks about optional plugins (dm_pix) it cannot load; none
    concerns a Dense/LSTM actor."""
    logger = logging.getLogger("jax2onnx.plugins.plugin_system")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings():   # and its own use of names jax deprecated (jax.core.DropVar)
            warnings.simplefilter("ignore", DeprecationWarning)
            yield
    finally:
        logger.setLevel(level)


def write_onnx(config: Config, step: Callable, path: Path, opset: int = DEFAULT_OPSET) -> None:
    missing = missing_onnx_packages()
    if missing:
        raise ImportError(f"the ONNX export needs {' and '.join(missing)}: {INSTALL_HINT}")
    with _quiet_jax2onnx():
        import jax2onnx
        import onnx
        inputs, outputs = io_names(config.agent.recurrent)
        model = jax2onnx.to_onnx(step, input_shapes(config), model_name=f"docrl_jax_{config.name}", opset=opset,
                                 input_names=inputs, output_names=outputs)
    model.doc_string = (f"docrl_jax actor {config.name}: ({', '.join(inputs)}) -> ({', '.join(outputs)}) per "
                        f"control step; see policy.json")
    onnx.checker.check_model(model)
    onnx.save(model, str(path))


def write_stablehlo(config: Config, step: Callable, path: Path, platforms: tuple[str, ...] = ("cpu",)) -> None:
    import jax
    import jax.numpy as jnp
    batch = jax.export.symbolic_shape(BATCH)[0]
    specs = [jax.ShapeDtypeStruct(shape, jnp.float32) for shape in input_shapes(config, batch)]
    exported = jax.export.export(jax.jit(step), platforms=tuple(platforms))(*specs)
    path.write_bytes(exported.serialize())


def numpy_weights(config: Config, params) -> dict[str, np.ndarray]:
    """The actor's parameters under Flax's names (lstm/ii/kernel, ..., dense_0/kernel, ...), the
    deterministic head as head/{kernel,bias}, and what numpy_policy.py needs to know of the network."""
    p = params["params"]
    head = p["head"]["mean" if config.agent.algo == "sac" else "out"]
    out = {"actor": np.array(config.agent.actor), "recurrent": np.array(config.agent.recurrent),
           "head/kernel": head["kernel"], "head/bias": head["bias"]}
    if config.agent.actor == "lstm":
        out.update({f"lstm/{gate}/{name}": value for gate, layer in p["lstm"].items() for name, value in layer.items()})
    else:
        out["num_hidden"] = np.array(len(config.agent.actor_hidden))
        out.update({f"{layer}/{name}": value for layer, leaf in p.items() if layer != "head"
                    for name, value in leaf.items()})
    return {k: np.asarray(v) for k, v in out.items()}


def write_numpy(config: Config, params, out_dir: Path) -> None:
    np.savez(out_dir / WEIGHTS_FILE, **numpy_weights(config, params))
    shutil.copyfile(Path(__file__).with_name(LOADER_FILE), out_dir / LOADER_FILE)
