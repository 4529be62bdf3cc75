"""Export a trained actor for deployment: ONNX, a jax.export StableHLO artefact and a NumPy-only
reference, with a `policy.json` manifest (docs/DEPLOY.md).

    from docrl_jax.export import export_policy
    manifest = export_policy("runs/d", "export/d", seed_index=0)    # the run's policy (which= as load_policy)

    manifest = export_shipped("td3_lstm", "export/td3_lstm")        # a policy shipped in the package

    python -m docrl_jax.export --run runs/d --out export/d      # the command (docrl_jax.export.cli)
    python -m docrl_jax.export --policy td3_lstm --out export/td3_lstm

Every export checks itself before it writes the manifest: each artefact, loaded back from the
directory, is run over a sequence of observations (its carry fed back) beside the JAX actor, and the
largest action difference is recorded in `policy.json` ("check"); above `CHECK_TOLERANCE` the export
fails. The ONNX artefact needs the `export` extra (jax2onnx, onnx, onnxruntime); the rest of the
package imports without it.
"""

from __future__ import annotations

import importlib.util
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from docrl_jax.errors import ExportError
from docrl_jax.export import artefacts, manifest as manifest_mod
from docrl_jax.export.artefacts import (DEFAULT_OPSET, EXPORT_FILES, FORMATS, INSTALL_HINT, MANIFEST_FILE,
                                        missing_onnx_packages)

CHECK_STEPS = 64
CHECK_TOLERANCE = 1e-5


def check_formats(formats: Sequence[str]) -> tuple[str, ...]:
    """The formats asked for, in the canonical order; ExportError for an unknown one, ImportError when
    ONNX is asked for without jax2onnx/onnx."""
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise ExportError(f"formats {', '.join(bad) or '(none)'}: valid formats are {', '.join(FORMATS)}")
    if "onnx" in formats and missing_onnx_packages():
        raise ImportError(f"the ONNX export needs {' and '.join(missing_onnx_packages())}: {INSTALL_HINT} "
                          f"(or leave onnx out of the formats)")
    return tuple(f for f in FORMATS if f in formats)


def prepare_out_dir(out_dir: str | Path, force: bool = False) -> Path:
    """Creates `out_dir` and proves it writable; refuses one that already holds an export unless
    `force` (then the previous export's files are removed, so none of them is left stale). Raises
    ExportError, or OSError for a directory that cannot be made or written."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ExportError(f"--out {str(out_dir)!r} is a file, not a directory")
    held = [name for name in EXPORT_FILES if (out_dir / name).exists()]
    if held and not force:
        raise ExportError(f"{str(out_dir)!r} already holds an export ({', '.join(held)}); choose another --out, "
                          f"or pass --force to replace it")
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=out_dir, prefix=".write_check"):
        pass
    for name in held:
        (out_dir / name).unlink()
    return out_dir


def check_observations(steps: int, size: int, seed: int = 0) -> np.ndarray:
    """`steps` observations of `size` floats in the ranges the env produces (`huauv.observation_bounds`),
    shaped (steps, 1, size): what `check_export` feeds every artefact and the JAX policy alike."""
    from docrl_jax.envs.huauv import observation_bounds
    rng = np.random.default_rng(seed)
    obs = rng.uniform(-1.0, 1.0, (steps, 1, size)).astype(np.float32)
    low, _ = observation_bounds(size)
    return np.where(low == 0.0, np.abs(obs), obs)   # the [0, 1] floats


def check_export(out_dir: Path, formats: Sequence[str], step, manifest: dict[str, Any],
                 steps: int = CHECK_STEPS) -> dict[str, Any]:
    """Runs each artefact of `out_dir` over `steps` observations, carry fed back, and a batch of 3,
    beside the JAX step function; returns the largest action differences."""
    import jax

    from docrl_jax.export.runners import open_artefact
    reference = jax.jit(step)
    obs = check_observations(steps, manifest["observation"]["size"])
    result: dict[str, Any] = {"steps": steps, "batch_sizes": [1, 3], "tolerance": CHECK_TOLERANCE,
                              "max_abs_action_diff": {}}
    for fmt in formats:
        if fmt == "onnx" and importlib.util.find_spec("onnxruntime") is None:
            result["max_abs_action_diff"][fmt] = f"not checked: onnxruntime is not installed ({INSTALL_HINT})"
            continue
        runner = open_artefact(out_dir, fmt, manifest=manifest)
        ref_carry, carry, worst = runner.initial_carry(), runner.initial_carry(), 0.0
        for o in obs:
            out = reference(o, *ref_carry)
            ref_action, ref_carry = (out[0], out[1:]) if ref_carry else (out, ())
            action, carry = runner.step(o, carry)
            worst = max(worst, float(np.max(np.abs(np.asarray(ref_action) - action))))
        batch = obs[:3, 0]
        out = reference(batch, *runner.initial_carry(3))
        action, _ = runner.step(batch, runner.initial_carry(3))
        worst = max(worst, float(np.max(np.abs(np.asarray(out[0] if runner.carry_names else out) - action))))
        if not worst <= CHECK_TOLERANCE:
            raise ExportError(f"the {fmt} artefact in {str(out_dir)!r} differs from the JAX actor by {worst:.3g} "
                              f"(tolerance {CHECK_TOLERANCE:g}); the export is not usable")
        result["max_abs_action_diff"][fmt] = worst
    return result


def export_actor(config, params, out_dir: str | Path, source: dict[str, Any],
                 formats: Sequence[str] = FORMATS, force: bool = False, opset: int = DEFAULT_OPSET,
                 platforms: Sequence[str] = ("cpu",)) -> dict[str, Any]:
    """Writes the actor `params` of `config` (one seed's actor params) to `out_dir` in `formats`,
    checks every artefact, then writes `policy.json` (returned). `source` says where the params came
    from (it is copied into the manifest)."""
    formats = check_formats(formats)
    if config.agent.frames > 1:
        raise ExportError(f"agent.frames {config.agent.frames}: the export writes LSTM and single-frame MLP "
                          f"actors; an actor reading stacked observations is not exported")
    out_dir = prepare_out_dir(out_dir, force)
    step = artefacts.step_function(config, params)
    inputs, outputs = manifest_mod.io_names(config.agent.recurrent)
    files: dict[str, Any] = {"manifest": MANIFEST_FILE}
    if "onnx" in formats:
        artefacts.write_onnx(config, step, out_dir / artefacts.ONNX_FILE, opset)
        files["onnx"] = {"file": artefacts.ONNX_FILE, "opset": opset, "inputs": inputs, "outputs": outputs,
                         "load": "onnxruntime.InferenceSession(path).run(None, {name: array, ...})"}
    if "stablehlo" in formats:
        artefacts.write_stablehlo(config, step, out_dir / artefacts.STABLEHLO_FILE, tuple(platforms))
        files["stablehlo"] = {"file": artefacts.STABLEHLO_FILE, "platforms": list(platforms), "inputs": inputs,
                              "outputs": outputs,
                              "load": "jax.export.deserialize(bytearray(open(path, 'rb').read())).call(*inputs)"}
    if "numpy" in formats:
        artefacts.write_numpy(config, params, out_dir)
        files["numpy"] = {"weights": artefacts.WEIGHTS_FILE, "loader": artefacts.LOADER_FILE,
                          "load": "NumpyPolicy(weights).step(observation, carry) -> (action, carry)"}
    manifest = manifest_mod.build(config, source, files, check={})
    manifest["check"] = check_export(out_dir, formats, step, manifest)
    tmp = out_dir / (MANIFEST_FILE + ".tmp")
    tmp.write_text(json.dumps(manifest, indent=1) + "\n")
    os.replace(tmp, out_dir / MANIFEST_FILE)
    return manifest


def export_policy(run_dir: str | Path, out_dir: str | Path, seed_index: int = 0, which: str | None = None,
                  formats: Sequence[str] = FORMATS, force: bool = False, opset: int = DEFAULT_OPSET,
                  platforms: Sequence[str] = ("cpu",)) -> dict[str, Any]:
    """Exports seed `seed_index`'s policy of the run in `run_dir` to `out_dir` (`which` as runs.load_policy's:
    None = the run's policy, best where kept, else final; the manifest's source.which says which); returns
    the manifest. Raises RunDirError (the run), ExportError (the output directory, a failed check),
    OSError (an output directory that cannot be written), ImportError (ONNX without its packages)."""
    from docrl_jax import checkpoint, runs
    formats = check_formats(formats)
    policy = runs.load_policy(run_dir, seed_index=seed_index, which=which)
    config = runs.read_config(run_dir)
    source = {"run_dir": str(Path(run_dir).resolve()), "seed_index": seed_index, "which": policy.which,
              "checkpoint_env_steps": checkpoint.latest_step(run_dir), "policy": policy.source}
    return export_actor(config, policy.params, out_dir, source, formats, force, opset, platforms)


def export_shipped(name: str, out_dir: str | Path, formats: Sequence[str] = FORMATS, force: bool = False,
                   opset: int = DEFAULT_OPSET, platforms: Sequence[str] = ("cpu",)) -> dict[str, Any]:
    """Exports the policy `name` shipped in the package (docrl_jax.pretrained) to `out_dir`; returns the
    manifest. Raises as `export_policy`, and pretrained.UnknownPolicy for a name it does not ship."""
    from docrl_jax import pretrained
    formats = check_formats(formats)
    policy = pretrained.load(name)
    source = {"shipped_policy": name, "policy": policy.source}
    return export_actor(pretrained.config(name), policy.params, out_dir, source, formats, force, opset, platforms)


__all__ = ["export_policy", "export_shipped", "export_actor", "prepare_out_dir", "check_formats", "FORMATS", "CHECK_TOLERANCE"]
