"""Seeds over devices: seed env steps/s and seed gradient updates/s on 1 device vs all local devices,
at the same seeds per device (docrl_jax.sharding; the programs of docrl_jax.train.programs).

    python benchmarks/seed_scaling.py                                   # td3_lstm, 1 and 2 seeds per GPU
    python benchmarks/seed_scaling.py --configs td3_lstm sac_lstm --num-envs 4096 --seeds-per-device 1 4
    python benchmarks/seed_scaling.py --device-counts 1 2 4 --num-envs 4096 --seeds-per-device 1
    python benchmarks/seed_scaling.py --smoke                           # CPU, 4 forced host devices, tiny
    python benchmarks/seed_scaling.py --plot-only k1/seed_scaling.json k2/seed_scaling.json --out DIR  # one figure

For each config, num_envs and seeds per device k, and each device count D (--device-counts,
default {1, all}): the run
trains k x D seeds over D devices (one seed per device runs the unbatched program, more are
vmapped). Compile one chunk (timed separately), run one warm-up chunk (fills the replay past
start_steps = 0 and seq_len, so every timed iteration learns), then time --repeats chunks; the
median gives
    seed env steps/s = env steps of all seeds per second (num_envs x iterations x seeds / time),
    seed updates/s   = gradient updates of all seeds per second,
and `efficiency` = (seed env steps/s on D devices) / (D x that on 1 device). Peak memory is the
largest over the devices used. Writes seed_scaling.json / .md / .png (seed_scaling_smoke.* with
--smoke) into --out (default benchmarks/results/); the figure plots seed env steps/s against the
device count, one line per (config, num_envs, seeds per device), with perfect scaling dashed.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time


SMOKE_DEVICES = 4
SMOKE_SETS = ["env.max_episode_steps=20", "agent.actor_hidden=[8]", "agent.critic_hidden=[16,16]",
              "replay.batch_size=8", "replay.seq_len=4", "replay.burn_in=2", "agent.n_step=2", "train.eval_episodes=2"]


def measure(name: str, num_envs: int, seeds_per_device: int, devices: int, iters: int, repeats: int,
            sets: list[str]) -> dict:
    import jax
    import numpy as np

    from common import time_chunks
    from docrl_jax import sharding
    from docrl_jax.config import load_config
    from docrl_jax.train import make_trainer
    from docrl_jax.train.programs import compile_programs

    num_seeds = seeds_per_device * devices
    overrides = [f"env.num_envs={num_envs}", f"train.log_every={num_envs * iters}", "train.start_steps=0",
                 f"train.num_seeds={num_seeds}", f"train.devices={devices}",
                 f"replay.buffer_size={max(50_000, 128 * num_envs)}", *sets]
    config = load_config(name, overrides)
    trainer = make_trainer(config)
    placement = sharding.seed_placement(config.train)
    t0 = time.perf_counter()
    programs, _ = compile_programs(config, placement.devices, tiered=False)  # init, chunk and evaluate, in parallel
    compile_s = time.perf_counter() - t0
    keys = placement.put_seeds(np.stack([jax.random.PRNGKey(s) for s in range(num_seeds)]))
    state = programs.init(keys, placement.put_replicated(np.asarray(trainer.total_env_steps, np.int32)))
    state, times, learn = time_chunks(programs.chunk, state, repeats, placement.get)
    med = statistics.median(times)
    peak = [(d.memory_stats() or {}).get("peak_bytes_in_use", 0) for d in placement.devices]
    upd = config.train.updates_per_step
    return {"config": name, "algo": config.agent.algo, "num_envs": num_envs, "seeds_per_device": seeds_per_device,
            "devices": devices, "num_seeds": num_seeds, "iters_per_chunk": trainer.iters_per_chunk,
            "updates_per_step": upd, "compile_s": round(compile_s, 2), "chunk_s_median": round(med, 4),
            "chunk_s_all": [round(t, 4) for t in times], "learning_iters_per_chunk": learn,
            "seed_env_steps_per_s": round(trainer.steps_per_chunk * num_seeds / med),
            "seed_updates_per_s": round(trainer.iters_per_chunk * upd * num_seeds / med, 1),
            "peak_memory_gib_per_device": round(max(peak) / 2**30, 3) if any(peak) else None,
            "device_kind": placement.devices[0].device_kind, "overrides": overrides}


def plot(rows: list[dict], path: str) -> None:
    """Seed env steps/s against devices, one line per (config, num_envs, seeds/device); dashed: D x the 1-device rate."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.5, 4))
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        groups.setdefault((r["config"], r["num_envs"], r["seeds_per_device"]), []).append(r)
    for (name, n, k), rs in groups.items():
        rs = sorted(rs, key=lambda r: r["devices"])
        d = [r["devices"] for r in rs]
        y = [r["seed_env_steps_per_s"] / 1e6 for r in rs]
        line, = ax.plot(d, y, "o-", label=f"{name}, {n} envs, {k} seed(s)/device")
        ax.plot(d, [y[0] * x / d[0] for x in d], "--", color=line.get_color(), alpha=0.5)
    ax.set_xlabel("devices")
    ax.set_ylabel("seed env steps/s (millions)")
    ax.set_xticks(sorted({r["devices"] for r in rows}))
    ax.set_title(f"Seeds over devices ({rows[0]['device_kind']}; dashed: perfect scaling)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--configs", nargs="+", default=["td3_lstm"])
    ap.add_argument("--num-envs", type=int, nargs="+", default=[1024])
    ap.add_argument("--seeds-per-device", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--device-counts", type=int, nargs="+", default=None,
                    help="device counts to measure (default: 1 and all local devices), e.g. 1 2 4")
    ap.add_argument("--iters", type=int, default=50, help="iterations per timed chunk")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--set", action="append", default=[], help="extra config overrides section.key=value")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    ap.add_argument("--smoke", action="store_true",
                    help=f"CPU check of the script: {SMOKE_DEVICES} forced host devices, num_envs 4, tiny networks, "
                         f"--iters 4 --repeats 2 (numbers mean nothing)")
    ap.add_argument("--plot-only", nargs="+", metavar="JSON",
                    help="measure nothing: draw the rows of these seed_scaling.json files (several invocations "
                         "on one machine) as one figure, --out/seed_scaling.png")
    args = ap.parse_args(argv)
    if args.plot_only:
        runs = [json.load(open(p)) for p in args.plot_only]
        rows = [r for run in runs for r in run["results"]]
        os.makedirs(args.out, exist_ok=True)
        plot(rows, os.path.join(args.out, "seed_scaling.png"))
        return 0
    if args.smoke:
        # Must precede JAX's initialisation (nothing above imports it).
        os.environ["XLA_FLAGS"] = (f"{os.environ.get('XLA_FLAGS', '')} "
                                   f"--xla_force_host_platform_device_count={SMOKE_DEVICES}")
        os.environ["JAX_PLATFORMS"] = "cpu"
        args.num_envs, args.iters, args.repeats, args.set = [4], 4, 2, SMOKE_SETS + args.set
    import jax

    from common import run_meta, write_results
    available = len(jax.local_devices())
    counts = args.device_counts or ([1] if available == 1 else [1, available])
    if any(d < 1 or d > available for d in counts):
        ap.error(f"--device-counts {counts}: each must be between 1 and the {available} local devices")
    counts = sorted(set(counts))
    meta = {**run_meta(), "local_devices": [str(d) for d in jax.local_devices()]}
    print(json.dumps(meta), flush=True)
    columns = [("config", "config"), ("num_envs", "num_envs"), ("seeds/device", "seeds_per_device"),
               ("devices", "devices"), ("seeds", "num_seeds"), ("compile (s)", "compile_s"),
               ("seed env steps/s", "seed_env_steps_per_s"), ("seed updates/s", "seed_updates_per_s"),
               ("efficiency", "efficiency"), ("peak mem/device (GiB)", "peak_memory_gib_per_device")]
    stem = "seed_scaling_smoke" if args.smoke else "seed_scaling"
    rows, table = [], ""
    for name in args.configs:
        for n in args.num_envs:
            for k in args.seeds_per_device:
                base = None
                for d in counts:
                    row = measure(name, n, k, d, args.iters, args.repeats, args.set)
                    base = base or row["seed_env_steps_per_s"]
                    row["efficiency"] = round(row["seed_env_steps_per_s"] / (d * base), 3)
                    rows.append(row)
                    print(json.dumps(row), flush=True)
                    table = write_results(args.out, stem, "Seeds over devices", meta, rows, columns)
    plot(rows, os.path.join(args.out, f"{stem}.png"))
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
