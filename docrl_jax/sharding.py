"""Seeds over devices and processes.

Every array of a run's state has the seeds as its leading axis (`train.num_seeds`). On one device
the programs (`docrl_jax.train.programs`) vmap over that axis, or run the unbatched program for one
seed. On D > 1 devices the axis is split over a one-axis mesh named 'seed'
(`Mesh(devices, ('seed',))`, arrays placed with `NamedSharding(mesh, P('seed'))`) and the programs
run under `jax.shard_map`: each device trains its num_seeds / D seeds, vmapped, or unbatched when it
holds one, with no communication between devices. A seed's numbers do not depend on the device it
runs on (seeds are independent), so a sharded run gives the numbers of a one-device run of the same
seeds, to float rounding: exactly when both run the same per-device program (tests/train/test_sharding.py).

Which devices (`train.devices`, see `plan_devices`):
  0 / 'all'  every device of every process, or the largest count that divides num_seeds when the
             devices do not (a note says how many stay idle and which seed counts would use all);
  N          the first N devices; N must divide num_seeds (clear error otherwise).
Seeds are never padded: a dummy seed would cost a real seed's device time, and the state's shape
would then depend on the device count, so a checkpoint could not be resumed on another one. With
even splits the state has the same shape on any device count, and a checkpoint (Orbax stores
global arrays) is restored onto the current devices whatever topology wrote it.

Multi-process (several hosts, or one process per GPU): `initialize_distributed` runs
`jax.distributed.initialize()` (the CLI's `--distributed`, or automatically when
JAX_COORDINATOR_ADDRESS and JAX_NUM_PROCESSES are set) and `shutdown_distributed` ends the session
when the run is over; `jax.devices()` in between lists every process's
devices and the mesh spans them, each process taking the same number of its local devices. Every
process runs the same program and the same Python loop (metrics are all-gathered so every process
takes the same decisions); only process 0 writes logs, metrics and TensorBoard, while checkpoints
are saved collectively (Orbax: every process writes its own shards, process 0 the metadata).
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
from typing import TYPE_CHECKING, Any, Mapping

import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from docrl_jax.errors import ConfigError

if TYPE_CHECKING:  # annotations only: this module needs no config at run time
    from docrl_jax.config import TrainConfig

SEED_AXIS = "seed"
ENV_COORDINATOR, ENV_NUM_PROCESSES, ENV_PROCESS_ID = "JAX_COORDINATOR_ADDRESS", "JAX_NUM_PROCESSES", "JAX_PROCESS_ID"


# ------------------------------------------------------------------------------------ processes
def distributed_from_env(environ: Mapping[str, str] = os.environ) -> bool:
    """True when the environment asks for a multi-process run without --distributed."""
    return ENV_COORDINATOR in environ and ENV_NUM_PROCESSES in environ


def initialize_distributed(environ: Mapping[str, str] = os.environ) -> None:
    """`jax.distributed.initialize()` before anything touches a device. The coordinator comes from
    JAX_COORDINATOR_ADDRESS (host:port of process 0), the process count and index from
    JAX_NUM_PROCESSES / JAX_PROCESS_ID; whatever is unset is auto-detected by JAX from the cluster
    (SLURM's srun, Open MPI's mpirun, Kubernetes, Cloud TPU). Does nothing when already
    initialised (a resume in the same process). Raises ConfigError."""
    if jax.distributed.is_initialized():
        return
    kwargs: dict[str, Any] = {}
    for name, arg in ((ENV_NUM_PROCESSES, "num_processes"), (ENV_PROCESS_ID, "process_id")):
        if environ.get(name):
            try:
                kwargs[arg] = int(environ[name])
            except ValueError:
                raise ConfigError(f"{name}={environ[name]!r}: must be an integer") from None
    if getattr(jax.config, "jax_cpu_collectives_implementation", "gloo") is None:  # CPU processes' all-gathers
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    try:
        jax.distributed.initialize(**kwargs)
    except (ValueError, TypeError, RuntimeError) as e:
        raise ConfigError(f"--distributed: jax.distributed.initialize() failed ({type(e).__name__}: {e}); set "
                          f"{ENV_COORDINATOR}=host:port of process 0, {ENV_NUM_PROCESSES} and {ENV_PROCESS_ID}, "
                          f"or launch under SLURM (srun) or Open MPI (mpirun)") from None


def shutdown_distributed() -> None:
    """Ends a multi-process run's `jax.distributed` session, every process together: a barrier (each
    has finished its collectives and its checkpoint writes), then `jax.distributed.shutdown()` (each
    process leaves the coordination service, process 0 stopping it after all have left), while the
    devices are still up. Left to JAX's exit handler, the devices are torn down first and the session
    after; two processes on two GPUs then each ended with GRPC 'WatchTasksAsync failed ... CANCELLED'
    lines. Does nothing in a single-process run."""
    if not jax.distributed.is_initialized():
        return
    barrier()
    jax.distributed.shutdown()


def barrier() -> None:
    """Waits for every process (nothing to wait for in a single-process run): every device of every
    process takes part in one sum, and this process waits for each of its own devices' part.
    `multihost_utils.sync_global_devices` is no such barrier: it reads one device's result per
    process, and the other devices' parts of its collective (and of `SeedPlacement.get`'s) may still be
    queued. A process that then exits drops them, and its peer waits for them for ever (seen: two CPU
    processes, one hung at exit in Gloo's connect, 1 run in 40 on a loaded machine). A device launches
    its collectives in order, so once this barrier's part is done, so are theirs."""
    if jax.process_count() == 1:
        return
    mesh = Mesh(np.asarray(jax.devices(), dtype=object), ("all",))
    ones = jax.make_array_from_process_local_data(NamedSharding(mesh, PartitionSpec("all")),
                                                  np.ones(jax.local_device_count(), np.int32))
    total = jax.jit(jax.numpy.sum, out_shardings=NamedSharding(mesh, PartitionSpec()))(ones)
    jax.block_until_ready([shard.data for shard in total.addressable_shards])


def is_primary() -> bool:
    """Process 0: the one that writes logs, metrics.csv and TensorBoard."""
    return jax.process_index() == 0


# ------------------------------------------------------------------------------------ devices
def device_line() -> str:
    """What a run is on, for the console: 'GPU: NVIDIA H100 80GB HBM3 (1 device)', or on a CPU that
    training needs a GPU and what runs here in minutes instead (the policies shipped in the package)."""
    devs = jax.devices()
    if devs[0].platform == "cpu":
        return (f"CPU ({os.cpu_count()} cores): no GPU found. Training needs a GPU (the packaged configs learn "
                "nothing here in minutes; see the ETA). To fly trained policies on this CPU instead: "
                "python -m docrl_jax.evaluate --policy td3_lstm --trials 10 --scenarios 2; "
                "python -m docrl_jax.render; python -m docrl_jax.export --policy td3_lstm --out export/td3_lstm")
    return f"{devs[0].platform.upper()}: {devs[0].device_kind} ({len(devs)} device{'s' if len(devs) > 1 else ''})"


def plan_devices(num_seeds: int, requested: int, available: int, processes: int = 1) -> tuple[int, str | None]:
    """(D, note): how many of the `available` devices (over `processes` processes, the same number
    each) the seeds are split over for `train.devices=requested` (0 = all), and a note when a
    default choice leaves devices idle. Pure; raises ConfigError naming the valid choices."""
    per_process = available // processes

    def fits(d: int) -> bool:
        return num_seeds % d == 0 and d % processes == 0 and d // processes <= per_process

    valid = [d for d in range(1, available + 1) if fits(d)]
    where = f"{available} device{'s' * (available > 1)}" + (f" over {processes} processes" if processes > 1 else "")
    if requested == 0:
        if not valid:
            raise ConfigError(f"train.num_seeds={num_seeds}: the {processes} processes must hold the same number "
                              f"of seeds; use a multiple of {processes} seeds")
        d = max(valid)
        note = None
        if d < available:
            more = [available * k for k in (1, 2, 3)]
            k = num_seeds // d
            each = f"{k} seed{'s' * (k > 1)}" + (" each" if d > 1 else "")
            note = (f"train.num_seeds={num_seeds} over {where}: using {d} device{'s' * (d > 1)} "
                    f"({each}), {available - d} idle; "
                    f"num_seeds {', '.join(map(str, more))}... would use all {available}")
        return d, note
    if requested > available:
        raise ConfigError(f"train.devices={requested}: only {where} visible; valid: 'all' or 1..{available}")
    if processes > 1 and requested % processes:
        raise ConfigError(f"train.devices={requested}: each of the {processes} processes must use the same "
                          f"number of devices; valid: 'all' or {[d for d in valid] or 'none for these seeds'}")
    if num_seeds % requested:
        raise ConfigError(f"train.devices={requested} does not divide train.num_seeds={num_seeds} (every device "
                          f"trains the same number of seeds; seeds are not padded); valid train.devices for "
                          f"{num_seeds} seeds on {where}: 'all' or {valid}, or set train.num_seeds to a multiple "
                          f"of {requested}")
    return requested, None


def seed_devices(train: TrainConfig) -> tuple[tuple[jax.Device, ...], str | None]:
    """The devices the seeds of `train` are split over (ordered by process, then local id), and
    `plan_devices`' note. Raises ConfigError."""
    processes = jax.process_count()
    by_process = [sorted((d for d in jax.devices() if d.process_index == p), key=lambda d: d.id)
                  for p in range(processes)]
    if len({len(ds) for ds in by_process}) != 1:
        raise ConfigError(f"the processes hold different numbers of devices ({[len(ds) for ds in by_process]}); "
                          f"give each the same (e.g. JAX_LOCAL_DEVICE_IDS or CUDA_VISIBLE_DEVICES)")
    d, note = plan_devices(train.num_seeds, train.devices, len(jax.devices()), processes)
    take = d // processes
    return tuple(dev for ds in by_process for dev in ds[:take]), note


def use_gspmd_partitioner() -> None:
    """Partition the multi-device programs with GSPMD instead of JAX's default, Shardy.

    Why: with jax/jaxlib 0.11.2 on two H200s (CUDA), XLA segfaults while compiling the shard_map'd
    init program under Shardy (tiny sizes too; autotuning, Triton GEMMs and compile parallelism are
    not the cause); with JAX_USE_SHARDY_PARTITIONER=0 the same programs compile and run
    (benchmarks/results/h200x2/README.md). The seed axis needs no partitioning decisions (shard_map,
    no communication), so the partitioner changes nothing in the numbers. A process-wide JAX flag,
    set only when a run spans several devices; skipped when this JAX no longer has the option."""
    try:
        jax.config.update("jax_use_shardy_partitioner", False)
    except (AttributeError, KeyError, ValueError):
        pass


@dataclasses.dataclass(frozen=True)
class SeedPlacement:
    """Where the seed axis lives, and moving values between the host and there.

    One device: arrays are left uncommitted on the default device, exactly as unsharded code does
    (so the single-device programs and their compile caches are unchanged). Several: global arrays
    sharded over the 'seed' mesh axis; host values must be equal on every process."""

    devices: tuple
    note: str | None = None

    @property
    def sharded(self) -> bool:
        return len(self.devices) > 1

    @property
    def mesh(self) -> Mesh:
        return Mesh(np.asarray(self.devices, dtype=object), (SEED_AXIS,))

    @property
    def seed_sharding(self) -> NamedSharding | None:
        """Sharding of every seed-batched array; None on one device."""
        return NamedSharding(self.mesh, PartitionSpec(SEED_AXIS)) if self.sharded else None

    def put_seeds(self, x) -> jax.Array:
        """A host array with leading axis num_seeds, split over the devices."""
        return self._put(np.asarray(x), self.seed_sharding)

    def seed_keys(self, seeds: list[int]) -> jax.Array:
        """`jax.random.PRNGKey` of each seed (computed `on_host`), split over the devices."""
        with on_host():
            keys = np.stack([np.asarray(jax.random.PRNGKey(s)) for s in seeds])
        return self.put_seeds(keys)

    def put_replicated(self, x) -> jax.Array:
        """A host value every device gets whole (e.g. the run length)."""
        return self._put(np.asarray(x), NamedSharding(self.mesh, PartitionSpec()) if self.sharded else None)

    @staticmethod
    def _put(x: np.ndarray, sharding) -> jax.Array:
        if sharding is None:
            return jax.numpy.asarray(x)
        return jax.make_array_from_callback(x.shape, sharding, lambda index: x[index])

    def get(self, tree: Any) -> Any:
        """Numpy copies of (seed-batched) device arrays, whole, on every process. Collective when
        there are several processes: every process must call it at the same point."""
        if jax.process_count() > 1:
            from jax.experimental import multihost_utils
            return multihost_utils.process_allgather(tree, tiled=True)
        return jax.device_get(tree)

    @staticmethod
    def any_process(flag: bool) -> bool:
        """True if `flag` is true on any process (collective), so that every process stops together."""
        if jax.process_count() == 1:
            return bool(flag)
        from jax.experimental import multihost_utils
        return bool(np.any(multihost_utils.process_allgather(np.asarray([flag]))))


@contextlib.contextmanager
def on_host():
    """Eager JAX operations inside run on the host's CPU: the small key arithmetic between programs. On a
    GPU each would be compiled for it, and a process's first GPU compile takes seconds (2.4 s of a cold
    launch on an H200, before its programs could start compiling). Random bits are the same on either."""
    try:   # this process's own (with several processes, jax.devices' first CPU is process 0's)
        cpu = jax.local_devices(backend="cpu")[0]
    except RuntimeError:   # JAX_PLATFORMS without the CPU
        cpu = None
    with jax.default_device(cpu) if cpu is not None else contextlib.nullcontext():
        yield


def seed_placement(train: TrainConfig) -> SeedPlacement:
    """Raises ConfigError for an impossible `train.devices`."""
    devices, note = seed_devices(train)
    return SeedPlacement(devices, note)
