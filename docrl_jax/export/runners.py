"""Each artefact of an export directory behind one interface, as a deployment would load it:

    runner = open_artefact(out_dir, "onnx" | "stablehlo" | "numpy", threads=1)
    carry = runner.initial_carry()                       # zeros, batch of one
    action, carry = runner.step(observation, carry)      # observation (1, 26) float32

Used by the export's own check, the tests and benchmarks/export_latency.py. The NumPy runner imports
the `numpy_policy.py` copied into the directory (not the package's), so what is checked is what ships;
StableHLO is deserialised and called with jax alone, as a program without docrl_jax would.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np

from docrl_jax.export.artefacts import LOADER_FILE, MANIFEST_FILE, ONNX_FILE, STABLEHLO_FILE, WEIGHTS_FILE


class Runner:
    def __init__(self, manifest: dict[str, Any], call):
        self.manifest = manifest
        self.carry_names = manifest["carry"]["names"]
        self.units = manifest["policy"]["units"]
        self._call = call   # (observation, *carry) -> (action, *carry)

    def initial_carry(self, batch_size: int = 1) -> tuple:
        return tuple(np.zeros((batch_size, self.units), np.float32) for _ in self.carry_names)

    def step(self, observation, carry: tuple = ()) -> tuple[np.ndarray, tuple]:
        action, *carry = self._call(np.asarray(observation, np.float32), *carry)
        return action, tuple(carry)


def read_manifest(out_dir: str | Path) -> dict[str, Any]:
    with open(Path(out_dir) / MANIFEST_FILE) as f:
        return json.load(f)


def load_numpy_module(out_dir: str | Path):
    """The numpy_policy module copied into an export directory, imported from there."""
    spec = importlib.util.spec_from_file_location("exported_numpy_policy", Path(out_dir) / LOADER_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def open_artefact(out_dir: str | Path, artefact: str, threads: int = 1, manifest: dict | None = None) -> Runner:
    out_dir = Path(out_dir)
    manifest = manifest or read_manifest(out_dir)
    if artefact == "numpy":
        policy = load_numpy_module(out_dir).NumpyPolicy(out_dir / WEIGHTS_FILE)

        def call(observation, *carry):
            action, carry = policy.step(observation, carry)
            return (action, *carry)
        return Runner(manifest, call)
    if artefact == "onnx":
        import onnxruntime as ort
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        session = ort.InferenceSession(str(out_dir / ONNX_FILE), options, providers=["CPUExecutionProvider"])
        inputs = [i.name for i in session.get_inputs()]
        return Runner(manifest, lambda *args: session.run(None, dict(zip(inputs, args))))
    if artefact == "stablehlo":
        import jax
        exported = jax.export.deserialize(bytearray((out_dir / STABLEHLO_FILE).read_bytes()))
        call = jax.jit(exported.call)

        def run(*args):
            return [np.asarray(x) for x in call(*args)] if manifest["carry"]["names"] else [np.asarray(call(*args))]
        return Runner(manifest, run)
    raise ValueError(f"artefact {artefact!r}: valid artefacts are numpy, onnx, stablehlo")
