"""Per-step latency of an exported policy on one CPU core: ONNX (onnxruntime), StableHLO (jax.export,
deserialised and jitted), the NumPy reference, and for comparison the JAX policy itself (load_policy's
act under jit), each called as a deployment calls it: one observation (batch 1), carry fed back.

    python benchmarks/export_latency.py                                  # the trained td3_lstm test policy
    python benchmarks/export_latency.py --run runs/d --steps 2000 --repeats 7 --cpu 0

The run's final policy (seed index 0; the recorded table timed final policies) is exported once
(python -m docrl_jax.export --which final, into a temporary directory); then each artefact runs in its
own process pinned to one core (`taskset -c CPU`) with one thread everywhere
(OMP/OpenBLAS/MKL_NUM_THREADS=1, onnxruntime intra_op_num_threads=1, XLA_FLAGS
"--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"). In it, after 200 warm-up
steps, `--repeats` runs of `--steps` steps are timed step by step (time.perf_counter_ns around the
call); a repeat's figure is the median step, the table gives the median over repeats, the 99th
percentile and the minimum over every step. Writes export_latency.json and export_latency.md into --out.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
ARTEFACTS = ("onnx", "stablehlo", "numpy", "jax")
LABELS = {"onnx": "ONNX (onnxruntime)", "stablehlo": "StableHLO (jax.export, jit)", "numpy": "NumPy reference",
          "jax": "JAX policy (load_policy, jit), not exported"}
ONE_THREAD = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
              "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"}
WARMUP = 200


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def worker(artefact: str, export_dir: Path, run: str, steps: int, repeats: int) -> dict:
    """Times one artefact in this process; returns per-repeat medians and all step times (ns)."""
    from docrl_jax.export import MANIFEST_FILE, check_observations
    size = json.loads((export_dir / MANIFEST_FILE).read_text())["observation"]["size"]
    obs = check_observations(steps + WARMUP, size, seed=1)
    if artefact == "jax":
        import jax

        from docrl_jax.runs import load_policy
        policy = load_policy(run, which="final")
        act = jax.jit(policy.act)

        def step(o, carry):
            carry, action = act(policy.params, carry, o, {}, None)
            return np.asarray(action), carry     # np.asarray waits for the result, as a deployment would
        initial = policy.init_carry
    else:
        from docrl_jax.export.runners import open_artefact
        runner = open_artefact(export_dir, artefact, threads=1)
        step, initial = runner.step, runner.initial_carry
    carry = initial()
    for o in obs[:WARMUP]:
        _, carry = step(o, carry)
    medians, every = [], []
    for _ in range(repeats):
        carry, times = initial(), []
        for o in obs[WARMUP:]:
            t0 = time.perf_counter_ns()
            _, carry = step(o, carry)
            times.append(time.perf_counter_ns() - t0)
        medians.append(statistics.median(times))
        every += times
    return {"artefact": artefact, "repeat_medians_ns": medians, "median_us": statistics.median(medians) / 1e3,
            "p99_us": float(np.percentile(every, 99)) / 1e3, "min_us": min(every) / 1e3,
            "affinity": sorted(os.sched_getaffinity(0))}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", default="tests/data/trained/td3_lstm",
                   help="run directory to export (default: %(default)s)")
    p.add_argument("--steps", type=int, default=2000, help="timed steps per repeat (default 2000)")
    p.add_argument("--repeats", type=int, default=7, help="timed repeats per artefact (default 7)")
    p.add_argument("--cpu", type=int, default=0, help="the core every artefact is pinned to (default 0)")
    p.add_argument("--out", default=str(HERE / "results" / "cpu" / "export_latency"))
    p.add_argument("--worker", choices=ARTEFACTS, help=argparse.SUPPRESS)
    p.add_argument("--export-dir", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.worker, Path(args.export_dir), args.run, args.steps, args.repeats)))
        return 0

    import datetime as dt

    from docrl_jax.export import export_policy
    from docrl_jax.export.manifest import versions
    rows, load = [], [round(x, 2) for x in os.getloadavg()]   # other work on the machine shows here
    with tempfile.TemporaryDirectory() as tmp:
        manifest = export_policy(args.run, Path(tmp) / "export", which="final")
        for artefact in ARTEFACTS:
            cmd = ["taskset", "-c", str(args.cpu), sys.executable, str(Path(__file__).resolve()), "--worker", artefact,
                   "--export-dir", str(Path(tmp) / "export"), "--run", args.run, "--steps", str(args.steps),
                   "--repeats", str(args.repeats)]
            proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **ONE_THREAD}, cwd=ROOT)
            if proc.returncode != 0:
                raise SystemExit(f"{artefact}: {proc.stderr.strip().splitlines()[-1:]}")
            row = json.loads(proc.stdout.strip().splitlines()[-1])
            row["steps_per_s"] = round(1e6 / row["median_us"])
            rows.append(row)
            print(f"{LABELS[artefact]}: median {row['median_us']:.1f} us/step, p99 {row['p99_us']:.1f} us, "
                  f"min {row['min_us']:.1f} us ({row['steps_per_s']:,} steps/s)", flush=True)
    given = argv if argv is not None else sys.argv[1:]
    meta = {"command": " ".join(["python", "benchmarks/export_latency.py", *given]),
            "date": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"), "cpu": cpu_model(),
            "cores_on_machine": os.cpu_count(), "load_average_1_5_15_min_at_start": load,
            "pinned_to": f"taskset -c {args.cpu}", "threads": ONE_THREAD,
            "policy": {**manifest["policy"], "source": manifest["source"]["policy"], "run": args.run},
            "steps": args.steps, "repeats": args.repeats, "warmup": WARMUP, "versions": versions()}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "export_latency.json").write_text(json.dumps({**meta, "results": rows}, indent=1) + "\n")
    lines = [f"# Exported policy, per-step latency on one CPU core ({meta['cpu']}, {meta['date']})", "",
             f"Command: `{meta['command']}`  ",
             f"Policy: {meta['policy']['config']} ({meta['policy']['network']}), {meta['policy']['source']} of "
             f"`{args.run}`  ",
             f"Pinned: `{meta['pinned_to']}`, one thread ({', '.join(f'{k}={v}' for k, v in ONE_THREAD.items())}; "
             f"onnxruntime intra_op_num_threads=1)  ",
             f"Per artefact: {args.repeats} repeats x {args.steps:,} steps (batch 1, carry fed back) after {WARMUP} "
             f"warm-up steps  ",
             f"Machine: {meta['cores_on_machine']} cores, load average {load} (1, 5, 15 min) at the start  ",
             f"Versions: {json.dumps(meta['versions'])}", "",
             "| artefact | median us/step | p99 us | min us | steps/s (1 / median) | repeat medians, us |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {LABELS[r['artefact']]} | {r['median_us']:.1f} | {r['p99_us']:.1f} | {r['min_us']:.1f} | "
              f"{r['steps_per_s']:,} | {', '.join(f'{m / 1e3:.1f}' for m in r['repeat_medians_ns'])} |" for r in rows]
    (out / "export_latency.md").write_text("\n".join(lines) + "\n")
    print(f"wrote {out}/export_latency.json, export_latency.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
