"""Which parts of the training chunk XLA spends its cold compile on: the chunk compiled alone, with one part
left out at a time, each variant in a fresh process with the compilation cache off, interleaved over rounds.

    python benchmarks/chunk_compile_parts.py --config td3_lstm --rounds 2 --out OUT

Variants (a part left out changes what the chunk computes: these programs are for timing only, never run):
    base         the chunk as the train command compiles it
    no_reset     the auto-reset's reset left out (an ended episode is not restarted)
    reset_cast   the reset's range cast left out (its first observation reads zeros)
    no_updates   train.updates_per_step=0 (no gradient updates)
    no_lanes     train.eval_alongside=false (no evaluation lanes)
Reported per variant: the StableHLO op count, seconds to trace and lower, seconds to compile (median over
rounds), and what leaving the part out saves against base.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time


VARIANTS = ("base", "no_reset", "reset_cast", "no_updates", "no_lanes")
_SETS = {"no_updates": ["train.updates_per_step=0"], "no_lanes": ["train.eval_alongside=false"]}


def _leave_out(variant: str) -> None:
    """Patches the env for the variants that leave out part of the auto-reset."""
    import jax.numpy as jnp

    from docrl_jax.envs import huauv, wrappers

    if variant == "no_reset":
        def step(self, state, action, layout=None):
            inner = state.replace(info={k: v for k, v in state.info.items() if k != "final_obs"})
            stepped = self.env.step(inner, action)
            return stepped.replace(info={**stepped.info, "final_obs": stepped.obs})
        wrappers.AutoResetWrapper.step = step
    elif variant == "reset_cast":
        reset = huauv.HUAUVEnv.reset

        def reset_without_cast(self, key, layout=None, plant=None):
            n = self.observation_size - 6   # the ranges of the observation
            self._sense = lambda *args: (jnp.zeros(20), jnp.zeros(n))
            try:
                return reset(self, key, layout, plant)
            finally:
                del self._sense
        huauv.HUAUVEnv.reset = reset_without_cast


def child(config_name: str, variant: str, sets: list[str]) -> dict:
    import jax
    import jax.numpy as jnp

    from docrl_jax.config import load_config
    from docrl_jax.train import programs
    from docrl_jax.train.program_store import enable_compile_cache

    enable_compile_cache("off")
    _leave_out(variant)
    config = programs.program_config(load_config(config_name, sets + _SETS.get(variant, [])), False)
    devices = tuple(jax.devices()[:1])
    init, chunk, _, _ = programs.jitted_programs(config, devices, False)
    keys = jax.ShapeDtypeStruct((1, 2), jnp.uint32)
    t0 = time.perf_counter()
    shape = jax.eval_shape(init, keys, jax.ShapeDtypeStruct((), jnp.int32))
    lowered = chunk.lower(shape)
    lower_s = time.perf_counter() - t0
    ops = sum(1 for line in lowered.as_text().splitlines() if "stablehlo." in line)
    t0 = time.perf_counter()
    lowered.compile()
    return {"variant": variant, "ops": ops, "lower_s": lower_s, "compile_s": time.perf_counter() - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--set", action="append", default=[], help="config override, repeatable")
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=VARIANTS)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--out", required=True)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print("RESULT " + json.dumps(child(args.config, args.child, args.set)), flush=True)
        return
    from docrl_jax.benchmarking import run_meta, write_results

    meta, rows, summary = run_meta(), {v: [] for v in args.variants}, []
    for r in range(args.rounds):
        for v in args.variants:
            cmd = [sys.executable, __file__, "--config", args.config, "--child", v, "--out", args.out]
            cmd += [x for s in args.set for x in ("--set", s)]
            out = subprocess.run(cmd, capture_output=True, text=True)
            line = [ln for ln in out.stdout.splitlines() if ln.startswith("RESULT ")]
            if not line:
                sys.exit(f"variant {v} failed:\n{out.stderr[-3000:]}")
            rows[v].append(json.loads(line[0][7:]))
            print(f"round {r} {v}: {rows[v][-1]}", flush=True)
        # Written after every round, so a device call's time limit keeps the rounds done.
        med = {v: {k: statistics.median(x[k] for x in rs) for k in ("ops", "lower_s", "compile_s")}
               for v, rs in rows.items()}
        base = med.get("base")
        summary = [{"variant": v, "ops": int(m["ops"]), "lower_s": f"{m['lower_s']:.1f}",
                    "compile_s": f"{m['compile_s']:.1f}", "each_s": ", ".join(f"{x['compile_s']:.1f}" for x in rows[v]),
                    "saves_s": f"{base['compile_s'] - m['compile_s']:.1f}" if base and v != "base" else ""}
                   for v, m in med.items()]
        write_results(args.out, "chunk_compile_parts", "Which parts of the chunk its cold compile goes to", meta,
                      summary, [("variant", "variant"), ("StableHLO ops", "ops"), ("trace + lower (s)", "lower_s"),
                                ("compile (s), median", "compile_s"), ("each round (s)", "each_s"),
                                ("saves against base (s)", "saves_s")])


if __name__ == "__main__":
    main()
