"""Run by tests/train/test_sharding.py in subprocesses, since XLA's forced host devices (and
jax.distributed) must be set up before JAX starts.

    python tests/train/_sharding_worker.py single OUT    one process, 4 CPU devices: runs under OUT/
    python tests/train/_sharding_worker.py multi OUT     one of 2 processes (JAX_COORDINATOR_ADDRESS,
                                                   JAX_NUM_PROCESSES, JAX_PROCESS_ID set), 2 devices each
    python tests/train/_sharding_worker.py shutdown OUT  one of 2 processes as for multi, no training: a
                                                   collective, then the session's end (shutdown_distributed)

Every run trains the same 4 seeds of TINY. XLA's backend optimisation is off in these processes:
it halves the compile time (the cost of these tests) and every run compared shares it.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

TINY = {
    "name": "tiny",
    "env": {"scenario": 1, "num_envs": 4, "wind": False, "max_goal_distance": 2.0, "progress_reward_scale": 1.0,
            "max_episode_steps": 20, "goal_water_fraction": 0.0, "start_water_fraction": 0.0},
    "agent": {"algo": "td3", "actor": "lstm", "actor_hidden": [8], "critic_hidden": [16, 16], "tau": 0.01},
    "replay": {"buffer_size": 400, "batch_size": 8, "seq_len": 4, "burn_in": 2},
    # 3 chunks of 64 env steps; updates from step 32: 40 gradient updates per seed in all.
    "train": {"total_env_steps": 192, "start_steps": 32, "updates_per_step": 1, "log_every": 64,
              "eval_every": 128, "eval_episodes": 4, "checkpoint_every": 128, "num_seeds": 4},
}
XLA_FLAGS = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"


def tiny_config(**train):
    from docrl_jax.config import config_from_dict
    raw = {k: (dict(v) if isinstance(v, dict) else v) for k, v in TINY.items()}
    raw["train"].update(train)
    return config_from_dict(raw)


def single(out: Path) -> None:
    """4 seeds on 4 devices and on 1, each interrupted after one chunk; then resumed on the same
    device count (four/, one/) and on the other (four_then_one/, one_then_four/)."""
    import jax
    import numpy as np

    from docrl_jax import sharding
    from docrl_jax.train import cli
    from docrl_jax.train import run as train_run
    from docrl_jax.train.programs import compile_programs
    from docrl_jax.config import ConfigError
    assert len(jax.devices()) == 4, jax.devices()
    summary = {"shardy_before": bool(getattr(jax.config, "jax_use_shardy_partitioner", False))}
    _build_a_multi_device_program(jax.devices())

    def go(name, devices, **kw):
        return train_run.run(tiny_config(devices=devices), out / name, show_progress=False, **kw)

    for name, devices, other, other_devices in (("four", 4, "four_then_one", 1), ("one", 1, "one_then_four", "all")):
        assert go(name, devices, stop_after_chunks=1) == cli.EXIT_INTERRUPTED
        shutil.copytree(out / name, out / other)
        assert go(name, devices, resume=True) == cli.EXIT_OK
        assert go(other, other_devices, resume=True) == cli.EXIT_OK

    # Where the 4-device programs put the state (already compiled: cheap).
    config = tiny_config(devices=4)
    placement = sharding.seed_placement(config.train)
    init = compile_programs(config, placement.devices)[0].init
    state = init(placement.put_seeds(np.stack([jax.random.PRNGKey(s) for s in range(4)])),
                 placement.put_replicated(np.int32(192)))
    summary["state_devices"] = sorted({len(leaf.sharding.device_set) for leaf in jax.tree.leaves(state)})
    summary["shard_seeds"] = sorted({leaf.addressable_shards[0].data.shape[0] for leaf in jax.tree.leaves(state)})
    # Multi-device programs are partitioned by GSPMD (Shardy segfaults XLA's GPU compile, jax 0.11.2).
    summary["shardy_after_sharded_programs"] = bool(getattr(jax.config, "jax_use_shardy_partitioner", False))
    # Uneven and impossible device counts (resolved, not compiled).
    devices, note = sharding.seed_devices(tiny_config(num_seeds=6).train)
    summary["six_seeds_default"] = [len(devices), note]
    try:
        sharding.seed_devices(tiny_config(devices=3).train)
    except ConfigError as e:
        summary["three_devices_error"] = str(e)
    summary["eight_devices_status"] = train_run.run(tiny_config(devices=8), out / "eight", show_progress=False)
    (out / "summary.json").write_text(json.dumps(summary))


def _build_a_multi_device_program(devices) -> None:
    """Builds (does not compile) a program over `devices` as the trainer builds its own, which switches
    JAX to the GSPMD partitioner (sharding.use_gspmd_partitioner), before any run. The program store's
    names, which also key the process's memo of compiled programs, include that flag: switched only
    inside the first run's compile, it would make every later run of the same programs in this
    process (the resumes) miss the memo and compile them again (a third of these workers' time)."""
    from jax.sharding import PartitionSpec

    from docrl_jax import sharding
    from docrl_jax.train import programs
    programs._over_seeds(lambda x: x, tuple(devices), (PartitionSpec(sharding.SEED_AXIS),))


def _gloo_on_loopback() -> None:
    """Gloo would bind to the address of the host name; keep the test on loopback (private API:
    skipped if it moves, then Gloo falls back to its default)."""
    import functools

    from jax._src.lib import _jax
    if hasattr(_jax, "make_gloo_tcp_collectives"):
        _jax.make_gloo_tcp_collectives = functools.partial(_jax.make_gloo_tcp_collectives, hostname="127.0.0.1")


def shutdown() -> int:
    """One of two processes: a collective over both, then the end of the session as the command
    line ends it. Prints what it saw; the test reads both processes' output."""
    _gloo_on_loopback()
    import jax
    import numpy as np

    from docrl_jax import sharding
    sharding.initialize_distributed()
    placement = sharding.SeedPlacement(tuple(jax.devices()))
    gathered = placement.get(placement.put_seeds(np.arange(4, dtype=np.int32)))
    sharding.shutdown_distributed()
    print(f"process {jax.process_index()}: gathered {gathered.tolist()}, session open after the end: "
          f"{jax.distributed.is_initialized()}", flush=True)
    return 0


def multi(out: Path) -> int:
    """One of two processes: the 4 seeds over 2 x 2 devices, interrupted after one chunk, then
    resumed through the command line (which picks the multi-process setup up from the environment)."""
    _gloo_on_loopback()
    import jax

    from docrl_jax import sharding
    from docrl_jax.train import cli
    from docrl_jax.train import run as train_run
    sharding.initialize_distributed()
    assert jax.process_count() == 2 and len(jax.devices()) == 4 and len(jax.local_devices()) == 2
    _build_a_multi_device_program(jax.devices())
    run_dir = out / "multi"
    first = train_run.run(tiny_config(), run_dir, show_progress=False, stop_after_chunks=1)
    second = cli.main(["--run-dir", str(run_dir), "--resume", "--no-progress"])
    print(f"process {jax.process_index()}: exit codes {first} {second}", flush=True)
    return 0 if (first, second) == (cli.EXIT_INTERRUPTED, cli.EXIT_OK) else 1


if __name__ == "__main__":
    mode, out = sys.argv[1], Path(sys.argv[2])
    count = {"single": 4, "multi": 2, "shutdown": 2}[mode]
    os.environ["XLA_FLAGS"] = (f"{os.environ.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={count} "
                               f"{XLA_FLAGS}")
    if mode == "single":
        single(out)
        sys.exit(0)
    sys.exit(shutdown() if mode == "shutdown" else multi(out))
