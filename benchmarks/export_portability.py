"""Does an export run where docrl_jax is not installed, with other versions of jax, onnxruntime and
numpy, and on a GPU? Two steps, on two machines:

    python benchmarks/export_portability.py prepare DIR     # here: export td3_lstm (cpu,cuda) + reference actions
    python3 benchmarks/export_portability.py check DIR --out RESULTS_DIR    # there: numpy, jax, onnxruntime only

`prepare` exports tests/data/trained/td3_lstm's final policy (the recorded results are of it) with
`--which final --platforms cpu,cuda` into DIR/export and saves 300 observations and the JAX policy's
actions for them (carry fed back) in DIR/reference.npz.
`check` imports nothing of docrl_jax (it says whether it could): it runs the StableHLO artefact on
every jax platform there, the ONNX one with onnxruntime and the NumPy one, over the same
observations, and writes the largest action differences with the versions and devices to
RESULTS_DIR/export_portability.json.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.metadata as metadata
import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np

STEPS = 300


def prepare(out: Path) -> None:
    root = Path(__file__).resolve().parents[1]
    import jax

    from docrl_jax.export import MANIFEST_FILE, check_observations, export_policy
    from docrl_jax.runs import load_policy
    run = root / "tests" / "data" / "trained" / "td3_lstm"
    export_policy(run, out / "export", which="final", platforms=("cpu", "cuda"), force=True)
    policy = load_policy(run, which="final")
    act = jax.jit(policy.act)
    obs, carry, actions = check_observations(STEPS, json.loads((out / "export" / MANIFEST_FILE).read_text())["observation"]["size"], seed=5), policy.init_carry(), []
    for o in obs:
        carry, action = act(policy.params, carry, o, {}, None)
        actions.append(np.asarray(action))
    np.savez(out / "reference.npz", obs=obs, actions=np.asarray(actions),
             jax=metadata.version("jax"), onnxruntime=metadata.version("onnxruntime"), numpy=np.__version__)
    print(f"wrote {out}/export and {out}/reference.npz")


def check(src: Path, results: Path) -> None:
    ref = np.load(src / "reference.npz")
    obs, expected, export = ref["obs"], ref["actions"], src / "export"

    def worst(step) -> float:
        c = h = np.zeros((1, 32), np.float32)
        actions = []
        for o in obs:
            a, c, h = step(o, c, h)
            actions.append(np.asarray(a))
        return float(np.abs(np.asarray(actions) - expected).max())

    import jax
    import onnxruntime as ort
    exported = jax.export.deserialize(bytearray((export / "policy.stablehlo").read_bytes()))
    diffs, ran_on = {}, {}
    for platform in exported.platforms:
        try:
            device = jax.devices(platform)[0]
        except RuntimeError:
            diffs[f"stablehlo on {platform}"] = "no such device here"
            continue
        call = jax.jit(exported.call)
        with jax.default_device(device):
            diffs[f"stablehlo on {device}"] = worst(lambda o, c, h: call(o, c, h))
            zeros = np.zeros((1, 32), np.float32)
            ran_on[str(device)] = sorted(str(d) for d in call(obs[0], zeros, zeros)[0].devices())
    session = ort.InferenceSession(str(export / "policy.onnx"), providers=["CPUExecutionProvider"])
    diffs["onnx (onnxruntime, CPU)"] = worst(lambda o, c, h: session.run(None, {"observation": o, "c": c, "h": h}))
    sys.path.insert(0, str(export))
    from numpy_policy import NumpyPolicy
    policy = NumpyPolicy(export / "policy_weights.npz")

    def numpy_step(o, c, h):
        action, (c, h) = policy.step(o, (c, h))
        return action, c, h
    diffs["numpy"] = worst(numpy_step)
    try:
        gpu = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True).stdout.strip()
    except OSError:
        gpu = ""
    out = {"command": " ".join(["python3", "benchmarks/export_portability.py", *sys.argv[1:]]),
           "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"), "gpu": gpu or "none",
           "docrl_jax_importable": importlib.util.find_spec("docrl_jax") is not None,
           "docrl_jax_imported": any(name.startswith("docrl_jax") for name in sys.modules),
           "versions_here": {name: metadata.version(name) for name in ("jax", "jaxlib", "onnxruntime", "numpy")},
           "versions_at_export": {name: str(ref[name]) for name in ("jax", "onnxruntime", "numpy")},
           "steps": int(len(obs)), "max_abs_action_diff": diffs, "stablehlo_result_devices": ran_on}
    results.mkdir(parents=True, exist_ok=True)
    (results / "export_portability.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out, indent=1))


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("step", choices=["prepare", "check"])
    p.add_argument("dir", type=Path)
    p.add_argument("--out", type=Path, help="check: where export_portability.json goes (default: DIR)")
    args = p.parse_args()
    if args.step == "prepare":
        prepare(args.dir)
    else:
        check(args.dir, args.out or args.dir)
    return 0


if __name__ == "__main__":
    sys.exit(main())
