"""A launch of the train command on one clock: when each program's compile (or load) starts and ends, when
the first chunk runs, how long the quick and the full builds of a tiered start take per chunk, how long the
run's evaluations by the evaluation program take. Each launch is a fresh process with an empty compilation
cache (`--warm`: each variant's launches share one, filled by a launch before the rounds that is not
reported; `--one-store`: one store for all variants, for variants that differ only in `env:` words); variants
are interleaved within each round.

    python3 benchmarks/launch_timeline.py --rounds 2 --variant base= \
        --variant ptxas0=quick:xla_gpu_disable_gpuasm_optimizations=true \
        --variant hold=hold:evaluate,chunk_full --out OUT

A variant's words:
- `quick:NAME=VALUE` adds an XLA option to the quick chunk's build (docrl_jax.train.programs.QUICK_CHUNK_OPTIONS);
- `late:NAME=VALUE` adds an XLA option to the evaluation program's build when it compiles beside training
  (a tiered start with evaluation lanes);
- `hold:P,Q` starts the compile of programs P, Q (init, evaluate, eval_starts, chunk_full) only once the
  chunk training starts with has compiled: how much the compiles beside it slow it;
- `env:NAME=VALUE` sets an environment variable of the launch (e.g. XLA_PYTHON_CLIENT_PREALLOCATE=false);
- `root:PATH` runs the tree at PATH (docrl_jax, configs, assets; e.g. a git-ignored .old) instead of this one.

The launch clock is the trainer's own (the process's start, docrl_jax.train.cli.process_start_time). Each
launch is `python -m docrl_jax.train --config CONFIG --set train.total_env_steps=...` (`--chunks` chunks).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from docrl_jax.benchmarking import run_meta


def _value(text: str):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return int(text)
    except ValueError:
        return text


def child(out: str, quick: dict, late: dict, hold: set, argv: list[str]) -> int:
    """Runs the train command in this process with its compiles, trainer builds and chunk calls timed. The
    heavy modules are imported where the command imports them, after it starts its programs' prefetch."""
    from docrl_jax.train import cli, program_store   # light: what the command imports first
    launch = cli.process_start_time()
    now = lambda: round(time.time() - launch, 3)  # noqa: E731
    events = {"compiles": [], "marks": [], "chunk_calls": [], "chunk_seconds": []}
    quick_done, quick_seen = threading.Event(), threading.Event()
    compile_lowered = program_store.compile_lowered

    def timed_compile(lowered, platform, options=None):
        name = str(lowered.compiler_ir("stablehlo").operation.attributes["sym_name"]).strip('"').removeprefix("jit_")
        if name == "chunk" and options:
            quick_seen.set()
        # A chunk compiled without options after a quick one is the full build of a tiered start.
        label = "chunk_full" if name == "chunk" and not options and quick_seen.is_set() else name
        if label == "evaluate" and late and quick_seen.is_set():
            options = {**(options or {}), **late}
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

    def import_heavy_and_time() -> None:
        """The command's own next step, `from docrl_jax.train.run import ...` (MJX, Flax, Orbax), timed; then
        the timers on what those modules hold."""
        start = now()
        import jax
        from docrl_jax import memory, sharding
        from docrl_jax.train import loop, metrics, programs, run
        events["marks"].append({"what": "import run", "start": start, "end": now(), "thread": "MainThread"})
        call = programs.Tiered.__call__

        def timed_call(self, *args):
            events["chunk_calls"].append({"t": now(), "build": "quick" if self.full is not None
                                          and not self.full.done() else "full"})
            return call(self, *args)

        add_chunk = loop.Eta.add_chunk

        def timed_chunk(self, seconds: float, learning: bool) -> None:   # every chunk's seconds, as the loop times it
            events["chunk_seconds"].append({"t": now(), "s": round(seconds, 4), "learning": bool(learning)})
            return add_chunk(self, seconds, learning)

        programs.QUICK_CHUNK_OPTIONS = {**programs.QUICK_CHUNK_OPTIONS, **quick}
        programs.Tiered.__call__, loop.Eta.add_chunk = timed_call, timed_chunk
        for module, attr, label in ((sharding, "device_line", "device_line"), (sharding, "seed_placement", "placement"),
                                    (memory, "check_memory", "check_memory"), (jax.random, "PRNGKey", "PRNGKey"),
                                    (sharding.SeedPlacement, "seed_keys", "seed_keys"), (loop, "eval_keys", "eval_keys"),
                                    (programs, "store_names", "store_names"), (programs, "_load", "load"),
                                    (programs, "make_trainer", "make_trainer"), (jax, "eval_shape", "eval_shape"),
                                    (metrics, "import_tensorboard", "import_tensorboard"),
                                    (loop.Evaluations, "now", "evaluate_now"),
                                    (loop.Evaluations, "finish", "evaluate_finish"), (run, "compile_programs", "compile_programs")):
            timed(module, attr, label)

    prefetch = program_store.prefetch

    def prefetch_then_import(config) -> None:
        start = now()
        prefetch(config)
        events["marks"].append({"what": "prefetch", "start": start, "end": now(), "thread": "MainThread"})
        import_heavy_and_time()

    program_store.compile_lowered, program_store.prefetch = timed_compile, prefetch_then_import
    timed(cli, "_resolve", "config")
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
    # The evaluation program of a tiered start is a Tiered too: its calls, inside the evaluations training
    # waits for, are not chunks, and a gap between chunks that spans such an evaluation is not a chunk's time.
    evals = [(m["start"], m["end"]) for m in ev["marks"] if m["what"] in ("evaluate_now", "evaluate_finish")]
    calls = [c for c in ev["chunk_calls"] if not any(s <= c["t"] <= e for s, e in evals)]
    for build in ("quick", "full"):
        gaps = [b["t"] - a["t"] for a, b in zip(calls, calls[1:])
                if a["build"] == build and not any(a["t"] < s < b["t"] for s, _ in evals)]
        row[f"{build} chunks"] = sum(c["build"] == build for c in calls)
        row[f"{build} s/chunk"] = round(statistics.median(gaps), 3) if gaps else None
    learning = [c["s"] for c in ev.get("chunk_seconds", []) if c["learning"]][1:]   # the first may warm up
    row["learning s/chunk"] = round(statistics.median(learning), 3) if learning else None
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variant", action="append", default=[], metavar="NAME=WORDS")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--chunks", type=int, default=20, help="chunks of 409,600 env steps per launch")
    ap.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                    help="another config override for every launch (repeatable)")
    ap.add_argument("--warm", action="store_true",
                    help="each variant's launches share a compilation cache and program store, filled first")
    ap.add_argument("--one-store", action="store_true",
                    help="with --warm: every variant's launches share one store, filled once by the first variant "
                         "(for variants that differ only in env: words, which compile the same programs)")
    ap.add_argument("--out")
    ap.add_argument("--retable", metavar="OUT", help="summarise a finished --out folder again from its launches' JSON")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    a, rest = ap.parse_known_args()
    if a.retable:
        retable(a.retable)
        return
    if a.child:
        spec = json.loads(os.environ["LAUNCH_TIMELINE_SPEC"])
        sys.exit(child(a.child, spec["quick"], spec["late"], set(spec["hold"]), rest[1:] if rest[:1] == ["--"] else rest))
    if not a.variant or not a.out:
        ap.error("give --out and at least one --variant NAME=WORDS")
    variants = {}
    for v in a.variant:
        name, _, words = v.partition("=")
        spec = {"quick": {}, "late": {}, "env": {}, "hold": [], "root": os.getcwd()}
        for w in words.split():
            kind, _, what = w.partition(":")
            if kind in ("quick", "late", "env") and "=" in what:
                k, _, val = what.partition("=")
                spec[kind][k] = val if kind == "env" else _value(val)
            elif kind == "hold":
                spec["hold"] += what.split(",")
            elif kind == "root":
                spec["root"] = os.path.abspath(what)
            else:
                ap.error(f"variant {name}: {w!r} is not quick:NAME=VALUE, late:NAME=VALUE, env:NAME=VALUE, hold:P,Q or root:PATH")
        variants[name] = spec
    if a.one_store and (not a.warm or any(s["quick"] or s["late"] or s["hold"] or s["root"] != os.getcwd()
                                          for s in variants.values())):
        ap.error("--one-store needs --warm and variants that differ only in env: words")
    os.makedirs(a.out, exist_ok=True)
    work = tempfile.mkdtemp(prefix="timeline_")
    rows, meta = [], run_meta()
    rounds = (["fill"] if a.warm else []) + list(range(a.rounds))
    for r in rounds:
        for name, spec in variants.items():
            if r == "fill" and a.one_store and name != next(iter(variants)):
                continue
            tag = f"{name}_r{r}"
            store = "all" if a.one_store else name
            cache = os.path.join(work, f"cache_{store}" if a.warm else f"cache_{tag}")
            path = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                    if p and os.path.abspath(p) != os.getcwd()]
            env = {**os.environ, **spec["env"], "PYTHONPATH": os.pathsep.join([spec["root"]] + path),
                   "LAUNCH_TIMELINE_SPEC": json.dumps(spec)}
            out = os.path.join(a.out, f"{tag}.json")
            cmd = [sys.executable, os.path.abspath(__file__), "--child", out, "--", "--config", a.config,
                   "--set", f"train.total_env_steps={409600 * a.chunks}",
                   *[w for x in a.set for w in ("--set", x)], "--run-dir", os.path.join(work, tag),
                   "--compile-cache", cache, "--no-progress"]
            t0 = time.time()
            with open(os.path.join(a.out, f"{tag}.log"), "w") as log:
                rc = subprocess.run(cmd, cwd=spec["root"], env=env, stdout=log, stderr=subprocess.STDOUT).returncode
            if rc != 0 or not os.path.exists(out):
                rows.append({"variant": name, "round": r, "failed": rc})
            else:
                rows.append(launch_row(name, r, round(time.time() - t0, 2), out))
            print(json.dumps(rows[-1]), flush=True)
            write_json(a.out, meta, variants, rows)
    write_table(a.out, meta, variants, rows, a.warm)


def launch_row(variant: str, rnd, spawn_to_exit: float, events: str) -> dict:
    """One launch's row of the table, from its events file."""
    with open(events) as f:
        return {"variant": variant, "round": rnd, "spawn_to_exit": spawn_to_exit, **summarise(json.load(f))}


def write_json(out: str, meta: dict, variants: dict, rows: list[dict]) -> None:
    with open(os.path.join(out, "launch_timeline.json"), "w") as f:
        json.dump({**meta, "variants": variants, "launches": rows}, f, indent=1)


def retable(out: str) -> None:
    """Rewrites launch_timeline.md/json of a finished folder from the per-launch JSON it holds."""
    with open(os.path.join(out, "launch_timeline.json")) as f:
        done = json.load(f)
    rows = []
    for r in done["launches"]:
        path = os.path.join(out, f"{r['variant']}_r{r['round']}.json")
        failed = "failed" in r or not os.path.exists(path)
        rows.append(r if failed else launch_row(r["variant"], r["round"], r["spawn_to_exit"], path))
    meta = {k: v for k, v in done.items() if k not in ("variants", "launches")}
    write_json(out, meta, done["variants"], rows)
    write_table(out, meta, done["variants"], rows, warm=any(r["round"] == "fill" for r in rows))


def write_table(out: str, meta: dict, variants: dict, rows: list[dict], warm: bool = False) -> None:
    keys = ["first_chunk", "launch_to_run_s", "make_trainer at", "chunk start", "chunk s", "launch_to_compiled_s",
            "launch_to_training_s", "init s", "evaluate s", "eval_starts s", "quick s/chunk", "quick chunks",
            "full s/chunk", "learning s/chunk", "evaluate_now s", "evaluate_finish s", "spawn_to_exit"]
    if warm:
        keys = ["first_chunk", "import run s", "launch_to_run_s", "load at", "load s", "launch_to_compiled_s",
                "seed_keys s", "launch_to_training_s", "learning s/chunk", "evaluate_now s", "spawn_to_exit"]
    lines = [f"# A {'warm' if warm else 'cold'} launch on one clock ({meta['gpu']}, {meta['date']})", "",
             f"Command: `{meta['command']}`  ",
             f"Versions: {meta['versions']}", "", "Medians over rounds (s after launch, s of compile, s per chunk):", "",
             "| variant | " + " | ".join(keys) + " |", "|---|" + "---|" * len(keys)]
    for name in variants:
        ok = [r for r in rows if r["variant"] == name and "failed" not in r and r["round"] != "fill"]
        cell = lambda k: (f"{statistics.median(v):.2f}" if (v := [r[k] for r in ok if r.get(k) is not None])  # noqa: E731
                          else "-")
        lines.append(f"| {name} | " + " | ".join(cell(k) for k in keys) + " |")
    lines += ["", "Variants: " + "; ".join(f"{n}: {s}" for n, s in variants.items())]
    with open(os.path.join(out, "launch_timeline.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
