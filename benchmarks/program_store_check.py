"""Do programs loaded from the program store compute what freshly compiled ones do, on this device?
Each phase is its own process, sharing one empty compile-cache folder, as successive launches do:

    python3 benchmarks/program_store_check.py --config td3_lstm --out DIR

1. compile:  an empty cache: the programs are compiled and stored;
2. load:     they are loaded from the store (no tracing);
3. rebuild:  the store is emptied, JAX's cache is kept: compiled from JAX's cache and stored again
             (on the CPU nothing is stored then: docrl_jax.train.program_store says why);
4. reload:   loaded from what phase 3 stored.
Every phase runs init, the evaluation and two training chunks from one seed and dumps the results;
each later phase is compared with phase 1, leaf by leaf. Writes program_store_check.json / .md.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

from docrl_jax.benchmarking import run_meta

PHASES = ("compile", "load", "rebuild", "reload")


def child(config_name: str, overrides: list, cache: str, dump: str) -> None:
    t0 = time.time()
    import jax
    import numpy as np

    from docrl_jax.config import load_config
    from docrl_jax.train.program_store import enable_compile_cache
    from docrl_jax.train.programs import compile_programs
    enable_compile_cache(cache)
    config = load_config(config_name, overrides)
    t1 = time.time()
    programs, seconds = compile_programs(config, tiered=False)   # the full chunk, as a load brings back
    keys = jax.numpy.stack([jax.random.PRNGKey(0)])
    state = programs.init(keys, jax.numpy.asarray(10 * config.train.log_every, jax.numpy.int32))
    ev = programs.evaluate(state.agent.actor_average, keys)
    ms = []
    for _ in range(2):
        state, m = programs.chunk(state)
        ms.append(m)
    out = jax.device_get({"eval": ev, "chunks": ms, "agent": state.agent})
    leaves = {str(i): np.asarray(x) for i, x in enumerate(jax.tree.leaves(out))}
    np.savez(dump, **leaves)
    with open(dump + ".json", "w") as f:
        json.dump({"origin": programs.origin, "programs_s": round(seconds, 2), "imports_config_s": round(t1 - t0, 2),
                   "total_s": round(time.time() - t0, 2)}, f)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default="td3_lstm")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="config overrides")
    ap.add_argument("--out", required=True)
    ap.add_argument("--child", nargs=2, metavar=("CACHE", "DUMP"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args.config, args.set, *args.child)
    import numpy as np
    work = tempfile.mkdtemp(prefix="store_check_")
    cache = os.path.join(work, "cache")
    rows, first = [], None
    for phase in PHASES:
        if phase == "rebuild":
            shutil.rmtree(os.path.join(cache, "programs"), ignore_errors=True)
        dump = os.path.join(work, f"{phase}.npz")
        subprocess.run([sys.executable, __file__, "--config", args.config, "--out", args.out, "--child", cache,
                        dump[:-4], *[f"--set={s}" for s in args.set]], check=True)
        with open(dump[:-4] + ".json") as f:
            row = {"phase": phase, **json.load(f)}
        got = np.load(dump)
        if first is None:
            first = got
        diffs = [float(np.nanmax(np.abs(got[k].astype(np.float64) - first[k].astype(np.float64)), initial=0.0))
                 for k in first.files]
        row.update(leaves=len(first.files), bitwise_equal=all(np.array_equal(got[k], first[k], equal_nan=True)
                                                              for k in first.files),
                   max_abs_diff=max(diffs), stored_entries=len(os.listdir(os.path.join(cache, "programs")))
                   if os.path.isdir(os.path.join(cache, "programs")) else 0)
        rows.append(row)
        print(row, flush=True)
    meta = run_meta()
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "program_store_check.json"), "w") as f:
        json.dump({**meta, "config": args.config, "phases": rows}, f, indent=1)
    cols = ["phase", "origin", "programs_s", "total_s", "stored_entries", "bitwise_equal", "max_abs_diff"]
    lines = [f"# Program store check ({meta['gpu']}, {meta['date']})", "", f"Command: `{meta['command']}`  ",
             f"Versions: {meta['versions']}", "", "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(str(r[c]) for c in cols) + " |" for r in rows]
    with open(os.path.join(args.out, "program_store_check.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
