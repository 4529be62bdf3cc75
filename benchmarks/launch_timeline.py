"""A cold launch of the train command on one clock: when each program's compile starts and ends, when the
first chunk runs, how long the quick and the full builds of a tiered start take per chunk. Each launch is a
fresh process with an empty compilation cache; variants are interleaved within each round.

    python3 benchmarks/launch_timeline.py --rounds 2 --variant base= \
        --variant ptxas0=quick:xla_gpu_disable_gpuasm_optimizations=true \
        --variant hold=hold:evaluate,chunk_full --out OUT

A variant's words:
- `quick:NAME=VALUE` adds an XLA option to the quick chunk's build (docrl_jax.train.programs.QUICK_CHUNK_OPTIONS);
- `hold:P,Q` starts the compile of programs P, Q (init, evaluate, eval_starts, chunk_full) only once the
  chunk training starts with has compiled: how much the compiles beside it slow it;
- `root:PATH` runs the tree at PATH (docrl_jax, configs, assets; e.g. a git-ignored .old) instead of this one.

The launch clock is the trainer's own (the process's start, docrl_jax.train.cli.process_start_time). Each
launch is `python -m docrl_jax.train --config CONFIG --set train.total_env_steps=...` (`--chunks` chunks).
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import run_meta  # noqa: E402


def _value(text: str):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return int(text)
    except ValueError:
        return text


def child(out: str, quick: dict, hold: set, argv: list[str]) -> int:
    """Runs the train command in this process with its compiles, trainer builds and chunk calls timed."""
    from docrl_jax.train import cli, program_store, programs
    launch = cli.process_start_time()
    now = lambda: round(time.time() - launch, 3)  # noqa: E731
    events = {"compiles": [], "marks": [], "chunk_calls": []}
    quick_done, quick_seen = threading.Event(), threading.Event()
    compile_lowered, call = program_store.compile_lowered, programs.Tiered.__call__

    def timed_compile(lowered, platform, options=None):
        name = str(lowered.compiler_ir("stablehlo").operation.attributes["sym_name"]).strip('"').removeprefix("jit_")
        if name == "chunk" and options:
            quick_seen.set()
        # A chunk compiled without options after a quick one is the full build of a tiered start.
        label = "chunk_full" if name == "chunk" and not options and quick_seen.is_set() else name
        queued = now()
        if label in hold:
            quick_done.wait()
        start = now()
        try:
            return compile_lowered(lowered, platform, options)
        finally:
            events["compiles"].append({"program": label, "queued": queued, "start": start, "end": now(),
                                       "options": options or {}})
            if label == "chunk":
                quick_done.set()

    depth = threading.local()

    def timed(module, attr: str, label: str) -> None:
        """Records each outermost call of module.attr (start, end, thread) as a mark named `label` (when the
        tree has it: an older one may not)."""
        f = getattr(module, attr, None)
        if f is None:
            return

        def wrapper(*args, **kwargs):
            outer = not getattr(depth, label, 0)
            setattr(depth, label, getattr(depth, label, 0) + 1)
            start = now()
            try:
                return f(*args, **kwargs)
            finally:
                setattr(depth, label, getattr(depth, label) - 1)
                if outer:
                    events["marks"].append({"what": label, "start": start, "end": now(),
                                            "thread": threading.current_thread().name})
        setattr(module, attr, wrapper)

    def timed_call(self, *args):
        events["chunk_calls"].append({"t": now(), "build": "quick" if self.full is not None and not self.full.done()
                                      else "full"})
        return call(self, *args)

    programs.QUICK_CHUNK_OPTIONS = {**programs.QUICK_CHUNK_OPTIONS, **quick}
    program_store.compile_lowered, programs.Tiered.__call__ = timed_compile, timed_call
    # The steps of a launch before its first compile (what a tiered start's chunk waits for).
    import jax
    from docrl_jax import memory, sharding
    from docrl_jax.train import loop, metrics
    for module, attr, label in ((cli, "_resolve", "config"), (program_store, "prefetch", "prefetch"),
                                (sharding, "device_line", "device_line"), (sharding, "seed_placement", "placement"),
                                (memory, "check_memory", "check_memory"), (jax.random, "PRNGKey", "PRNGKey"),
                                (sharding.SeedPlacement, "seed_keys", "seed_keys"), (loop, "eval_keys", "eval_keys"),
                                (programs, "store_names", "store_names"), (programs, "_load", "load"),
                                (programs, "make_trainer", "make_trainer"), (jax, "eval_shape", "eval_shape"),
                                (metrics, "import_tensorboard", "import_tensorboard")):
        timed(module, attr, label)
    _import = importlib.import_module("docrl_jax.train.run")   # what cli imports after its config
    events["marks"].append({"what": "import run", "start": 0.0, "end": now(), "thread": "MainThread"})
    timed(_import, "compile_programs", "compile_programs")
    status = cli.main(argv)
    events["exit"] = now()   # the process may wait on after this for a full build to be stored
    run_dir = argv[argv.index("--run-dir") + 1]
    with open(os.path.join(run_dir, "startup.json")) as f:
        events["startup"] = json.load(f)
    with open(out, "w") as f:
        json.dump(events, f, indent=1)
    return status


def summarise(ev: dict) -> dict:
    """One launch's figures (seconds on the launch clock)."""
    row = {"first_chunk": ev["startup"]["launch_to_first_chunk_s"], "run_end": ev["exit"],
           **{k: ev["startup"][k] for k in ("launch_to_run_s", "launch_to_compiled_s", "launch_to_training_s")}}
    for m in ev["marks"]:   # the first call of each, on the main thread
        if m["thread"] == "MainThread" and f"{m['what']} at" not in row:
            row[f"{m['what']} at"], row[f"{m['what']} s"] = m["start"], round(m["end"] - m["start"], 2)
    for c in ev["compiles"]:
        row[f"{c['program']} start"] = c["start"]
        row[f"{c['program']} s"] = round(c["end"] - c["start"], 2)
    calls = ev["chunk_calls"]
    for build in ("quick", "full"):
        gaps = [b["t"] - a["t"] for a, b in zip(calls, calls[1:]) if a["build"] == build]
        row[f"{build} chunks"] = sum(c["build"] == build for c in calls)
        row[f"{build} s/chunk"] = round(statistics.median(gaps), 3) if gaps else None
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variant", action="append", default=[], metavar="NAME=WORDS")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--chunks", type=int, default=20, help="chunks of 409,600 env steps per launch")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="another config override for every launch (repeatable)")
    ap.add_argument("--out")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a, rest = ap.parse_known_args()
    if a.child:
        spec = json.loads(os.environ["LAUNCH_TIMELINE_SPEC"])
        sys.exit(child(a.child, spec["quick"], set(spec["hold"]), rest[1:] if rest[:1] == ["--"] else rest))
    if not a.variant or not a.out:
        ap.error("give --out and at least one --variant NAME=WORDS")
    variants = {}
    for v in a.variant:
        name, _, words = v.partition("=")
        spec = {"quick": {}, "hold": [], "root": os.getcwd()}
        for w in words.split():
            kind, _, what = w.partition(":")
            if kind == "quick" and "=" in what:
                k, _, val = what.partition("=")
                spec["quick"][k] = _value(val)
            elif kind == "hold":
                spec["hold"] += what.split(",")
            elif kind == "root":
                spec["root"] = os.path.abspath(what)
            else:
                ap.error(f"variant {name}: {w!r} is not quick:NAME=VALUE, hold:P,Q or root:PATH")
        variants[name] = spec
    os.makedirs(a.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="timeline_")
    rows, meta = [], run_meta()
    for r in range(a.rounds):
        for name, spec in variants.items():
            tag = f"{name}_r{r}"
            path = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                    if p and os.path.abspath(p) != os.getcwd()]
            env = {**os.environ, "PYTHONPATH": os.pathsep.join([spec["root"]] + path),
                   "LAUNCH_TIMELINE_SPEC": json.dumps(spec)}
            out = os.path.join(a.out, f"{tag}.json")
            cmd = [sys.executable, os.path.abspath(__file__), "--child", out, "--", "--config", a.config,
                   "--set", f"train.total_env_steps={409600 * a.chunks}",
                   *[w for x in a.set for w in ("--set", x)], "--run-dir", os.path.join(work, tag),
                   "--compile-cache", os.path.join(work, f"cache_{tag}"), "--no-progress"]
            t0 = time.time()
            with open(os.path.join(a.out, f"{tag}.log"), "w") as log:
                rc = subprocess.run(cmd, cwd=spec["root"], env=env, stdout=log, stderr=subprocess.STDOUT).returncode
            if rc != 0 or not os.path.exists(out):
                rows.append({"variant": name, "round": r, "failed": rc})
            else:
                with open(out) as f:
                    rows.append({"variant": name, "round": r, "spawn_to_exit": round(time.time() - t0, 2),
                                 **summarise(json.load(f))})
            print(json.dumps(rows[-1]), flush=True)
            with open(os.path.join(a.out, "launch_timeline.json"), "w") as f:
                json.dump({**meta, "variants": variants, "launches": rows}, f, indent=1)
    write_table(a.out, meta, variants, rows)


def write_table(out: str, meta: dict, variants: dict, rows: list[dict]) -> None:
    keys = ["first_chunk", "launch_to_run_s", "make_trainer at", "chunk start", "chunk s", "launch_to_compiled_s",
            "launch_to_training_s", "init s", "evaluate s", "eval_starts s", "quick s/chunk", "quick chunks",
            "spawn_to_exit"]
    lines = [f"# A cold launch on one clock ({meta['gpu']}, {meta['date']})", "", f"Command: `{meta['command']}`  ",
             f"Versions: {meta['versions']}", "", "Medians over rounds (s after launch, s of compile, s per chunk):", "",
             "| variant | " + " | ".join(keys) + " |", "|---|" + "---|" * len(keys)]
    for name in variants:
        ok = [r for r in rows if r["variant"] == name and "failed" not in r]
        cell = lambda k: (f"{statistics.median(v):.2f}" if (v := [r[k] for r in ok if r.get(k) is not None])  # noqa: E731
                          else "-")
        lines.append(f"| {name} | " + " | ".join(cell(k) for k in keys) + " |")
    lines += ["", "Variants: " + "; ".join(f"{n}: {s}" for n, s in variants.items())]
    with open(os.path.join(out, "launch_timeline.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
