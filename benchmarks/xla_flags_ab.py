"""XLA flags A/B: the run's own compiled chunk and evaluation under several `XLA_FLAGS` (or JAX settings),
each variant in a fresh process (XLA reads its flags once), interleaved over rounds.

    python benchmarks/xla_flags_ab.py --config td3_lstm --rounds 3 \
        --variant base= --variant graphs=--xla_gpu_enable_command_buffer=+WHILE,+CONDITIONAL --out OUT

A variant's words that start with `--` are XLA flags; words `JAX_NAME=VALUE` are set in the child's
environment, where JAX reads them as its config (e.g. `JAX_THREEFRY_GPU_KERNEL_LOWERING=1`).

Each process compiles the train command's programs (`docrl_jax.train.programs.compile_programs`,
compilation cache off, or with `--cache fresh` an empty one of its own: every variant really compiles), runs init and `--warmup` chunks (past
`train.start_steps`, so the timed chunks learn), then times `--chunks` chunks and `--evals`
evaluations on fixed keys, of the initial actor (the same in every variant: one fixed workload) and
of the trained one. Reported per variant: compile seconds, median chunk seconds and env steps/s,
median evaluation seconds, and the trained actor's success rates, which must stay close across the
flags (the flags may only change speed; GPU reductions are not bit-reproducible, so a trained actor
differs a little between processes anyway). Medians over all rounds' timings.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time



def child(config_name: str, sets: list[str], warmup: int, chunks: int, evals: int) -> dict:
    import jax

    from docrl_jax.config import load_config
    from docrl_jax.train.chunks import schedule
    from docrl_jax.train.evaluation import eval_keys
    from docrl_jax.train.program_store import enable_compile_cache
    from docrl_jax.train.programs import compile_programs

    enable_compile_cache(os.environ["DOCRL_JAX_COMPILE_CACHE"])   # 'off', or a fresh folder (--cache fresh)
    config = load_config(config_name, sets)
    t0 = time.time()
    programs, _ = compile_programs(config, tiered=False)   # every program compiled whole, the full chunk timed
    compile_s = time.time() - t0
    n = config.train.num_seeds
    keys = jax.random.split(jax.random.PRNGKey(config.train.seed), n)
    state = programs.init(keys, jax.numpy.int32(config.train.total_env_steps))
    # The initial actor is the same in every variant (init is deterministic), so its evaluation times
    # one fixed workload; the trained actor's differs a little between variants (GPU reductions).
    untrained = jax.tree.map(jax.numpy.copy, state.agent.actor_average)
    for _ in range(warmup):
        state, m = programs.chunk(state)
    jax.block_until_ready(m)
    chunk_s = []
    for _ in range(chunks):
        t0 = time.perf_counter()
        state, m = programs.chunk(state)
        jax.block_until_ready(m)
        chunk_s.append(time.perf_counter() - t0)
    ekeys = eval_keys([config.train.seed] * n, 0)

    def timed_evals(params):
        seconds, result = [], None
        for _ in range(evals):
            t0 = time.perf_counter()
            result = jax.block_until_ready(programs.evaluate(params, ekeys))
            seconds.append(time.perf_counter() - t0)
        return seconds, result

    eval0_s, _ = timed_evals(untrained)
    eval_s, result = timed_evals(state.agent.actor_average)
    return {"compile_s": compile_s, "chunk_s": chunk_s, "eval_s": eval_s, "eval0_s": eval0_s,
            "steps_per_chunk": schedule(config).steps_per_chunk * n,
            "learn_iters": int(jax.device_get(m["learn_iters"]).min()),
            "eval": {k: float(jax.device_get(v).mean()) for k, v in result.items() if k.startswith("success")}}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", default="td3_lstm")
    p.add_argument("--variant", action="append", default=[], metavar="NAME=FLAGS",
                   help="a name and the XLA_FLAGS added to the environment's (empty: none added); "
                        "JAX_NAME=VALUE words are JAX settings set in the child's environment")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--chunks", type=int, default=5)
    p.add_argument("--evals", type=int, default=3)
    p.add_argument("--set", action="append", default=[], dest="sets", metavar="KEY=VALUE")
    p.add_argument("--cache", choices=["off", "fresh"], default="off",
                   help="the compilation cache (and program store) of each child: off, or an empty folder of "
                        "its own (what a cold launch of the train command compiles with)")
    p.add_argument("--out", required=True)
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.child:
        print(json.dumps(child(a.config, a.sets, a.warmup, a.chunks, a.evals)))
        return

    if not a.variant:
        p.error("give at least one --variant NAME=FLAGS")
    from common import run_meta, write_results
    variants = dict(v.split("=", 1) for v in a.variant)
    runs: dict[str, list[dict]] = {name: [] for name in variants}
    for _ in range(a.rounds):
        for name, flags in variants.items():
            jax_vars = dict(w.split("=", 1) for w in flags.split() if w.startswith("JAX_"))
            xla = " ".join(w for w in flags.split() if not w.startswith("JAX_"))
            env = {**os.environ, **jax_vars, "XLA_FLAGS": f"{os.environ.get('XLA_FLAGS', '')} {xla}".strip(),
                   "DOCRL_JAX_COMPILE_CACHE": "off" if a.cache == "off" else tempfile.mkdtemp(prefix="xla_ab_cache_")}
            cmd = [sys.executable, __file__, "--child", "--config", a.config, "--warmup", str(a.warmup),
                   "--chunks", str(a.chunks), "--evals", str(a.evals), "--out", a.out,
                   *[x for s in a.sets for x in ("--set", s)]]
            proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
            if proc.returncode != 0:
                runs[name].append({"error": proc.stderr.strip().splitlines()[-1:] or ["?"]})
                print(f"{name}: failed: {proc.stderr[-2000:]}", file=sys.stderr)
                continue
            runs[name].append(json.loads(proc.stdout.strip().splitlines()[-1]))
            print(name, json.dumps(runs[name][-1]), flush=True)
    rows = []
    for name, results in runs.items():
        ok = [r for r in results if "error" not in r]
        if not ok:
            rows.append({"variant": name, "flags": variants[name], "compile_s": "failed", "chunk_s": "-",
                         "env_steps_per_s": "-", "eval0_s": "-", "eval_s": "-", "eval": results[0]["error"][0][:120]})
            continue
        chunk = statistics.median(t for r in ok for t in r["chunk_s"])
        rows.append({"variant": name, "flags": variants[name],
                     "compile_s": round(statistics.median(r["compile_s"] for r in ok), 1),
                     "chunk_s": round(chunk, 4), "env_steps_per_s": int(ok[0]["steps_per_chunk"] / chunk),
                     "eval0_s": round(statistics.median(t for r in ok for t in r["eval0_s"]), 4),
                     "eval_s": round(statistics.median(t for r in ok for t in r["eval_s"]), 4),
                     "eval": "; ".join(f"{k} {v:.2f}" for k, v in ok[0]["eval"].items()),
                     "runs": len(ok), "raw": results})
    columns = [("variant", "variant"), ("XLA_FLAGS or JAX settings added", "flags"), ("compile s", "compile_s"),
               ("chunk s (median)", "chunk_s"), ("env steps/s", "env_steps_per_s"),
               ("evaluation s, initial actor", "eval0_s"), ("evaluation s, trained actor", "eval_s"),
               ("trained actor's evaluation (first round)", "eval")]
    print(write_results(a.out, "xla_flags_ab", f"XLA flags A/B, {a.config}", run_meta(), rows, columns))


if __name__ == "__main__":
    main()
