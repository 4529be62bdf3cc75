"""The compiled programs of a run (init, chunk, evaluate; with train.eval_alongside also eval_starts,
the first states of an evaluation's episodes for the chunk's lanes), built for the devices the seeds are split
over and compiled once per process. JAX's persistent compilation cache makes the next process skip
compiling, and the program store beside it skips tracing too; both are set up in
docrl_jax.train.program_store.

On one device the programs vmap over the seeds (one seed: the unbatched program on a seed axis of
size 1, because under vmap a per-seed `lax.cond` becomes a select that computes both branches, so
the delayed actor update and the pre-learning phase would cost a full update on every step). On
several devices (train.devices, docrl_jax.sharding) shard_map gives each device its block of seeds;
every input and output keeps the seed axis, sharded over the 'seed' mesh axis.

A cold start on a GPU (one process) compiles the chunk twice (`Tiered`): a quick build that training starts
with (the same computation, less to compile and slower to run: random draws as kernel calls, `kernel_random`;
the actor's sequence loop rolled, `quick_config`; cuBLAS matrix products, `QUICK_CHUNK_OPTIONS`), and the
full build, compiled beside it, that takes over from the next chunk once it is ready and is the one stored.
init, evaluate and eval_starts, whose speed hardly counts, get kernel-call random draws only. Such a start
returns once init (and eval_starts) are compiled, so the run initialises while its chunk compiles; with
evaluation lanes the evaluation program, needed only before a checkpoint and at the end, compiles after the
quick chunk, without autotuning (`BESIDE_TRAINING_OPTIONS`).

traced=True (sweeps): init(keys, total, hp) and chunk(state, hp) also take the agent's
hyperparameters (`algorithms.HParams`, one float32 per seed row), so rows that differ only in them
run in one program; the config's own values of those fields are then unused (and normalised away,
so one compilation serves any such values). The evaluation reads no HParams: a sweep and a plain
run of the same shapes share it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from concurrent.futures import Future, ThreadPoolExecutor, wait
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec

from docrl_jax import sharding
from docrl_jax.algorithms.common import HParams
from docrl_jax.config import Config
from docrl_jax.train import program_store
from docrl_jax.train.program_store import program_config, store_names
from docrl_jax.train.trainer import make_trainer

# ------------------------------------------------------------------ the programs
class Programs(NamedTuple):
    init: Callable        # (keys (S, 2), total env steps, [hp]) -> RunnerState stacked over seeds
    chunk: Callable       # (RunnerState, [hp]) -> (RunnerState, chunk metrics); donates its state
    evaluate: Callable    # (actor params stacked over seeds, keys (S, 2)) -> per-seed eval metrics
    state_shape: Any      # the RunnerState's shapes (what a checkpoint is restored into)
    origin: str = "compiled"  # "compiled" in this process, or "loaded" from the program store
    eval_starts: Callable | None = None  # keys (S, 2) -> the evaluation lanes' first states (train.eval_alongside)


def hparams_shape(num_rows: int, config: Config):
    """Shapes of the traced programs' `hp` argument: one float32 per seed row and HParams leaf."""
    return jax.tree.map(lambda _: jax.ShapeDtypeStruct((num_rows,), jnp.float32),
                        HParams.from_agent_config(config.agent))


# The one memo of compiled programs, by their store entry names: a resume or a second run of the
# same shapes in one process compiles nothing.
_COMPILED: dict = {}


def compile_programs(config: Config, devices: tuple | None = None, traced: bool = False,
                     tiered: bool | None = None) -> tuple[Programs, float]:
    """The run's programs for `devices` (the tuple from `sharding.seed_devices`; None resolves
    train.devices here, for callers without a run's placement). Memoised in the process; else loaded
    from the program store when an earlier launch built them (docrl_jax.train.program_store: no env
    build, no tracing); else compiled ahead of time, all at once in threads (XLA compiles them in
    parallel), and stored (in a background thread). Returns them and the seconds this call spent (0 when memoised).
    `tiered`: None = a `Tiered` chunk when compiling on a GPU in one process (training starts sooner);
    False = the full chunk alone, compiled before this returns (what a benchmark that times chunks needs)."""
    devices = sharding.seed_devices(config.train)[0] if devices is None else devices
    config = program_config(config, traced)
    # The store's entry names describe the programs, so they key the memo too: the evaluation alone
    # (a sweep and a plain run of the same shapes share it) and the three together.
    names = store_names(config, devices, traced)
    whole = tuple(names.values())
    if whole in _COMPILED:
        return _COMPILED[whole], 0.0
    t0 = time.time()
    store = program_store.folder()
    compiled = _load(store, names, devices) if store is not None else None
    origin = "loaded"
    if compiled is None:
        compiled, storable = _compile(config, devices, traced, names, store, tiered)
        origin = "compiled"
        if store is not None and storable:  # written beside the run's start, not before it
            program_store.save_in_background(store, {names[what]: compiled[what] for what in storable})
    _COMPILED[names["evaluate"]] = compiled["evaluate"]
    # The runner state's shapes, as the init program returns them (what a checkpoint is restored into).
    state_shape = jax.tree.map(lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype), compiled["init"].out_info)
    _COMPILED[whole] = Programs(compiled["init"], compiled["chunk"], compiled["evaluate"], state_shape, origin,
                                compiled.get("eval_starts"))
    return _COMPILED[whole], time.time() - t0


def _load(store, names: dict, devices) -> dict | None:
    """All three programs from the store, loaded in threads, or None if any is missing."""
    with ThreadPoolExecutor(len(names)) as pool:
        done = {what: pool.submit(program_store.load, store, name, devices) for what, name in names.items()}
        loaded = {what: f.result() for what, f in done.items()}
    return loaded if all(p is not None for p in loaded.values()) else None


def _compile(config: Config, devices: tuple, traced: bool, names: dict, store,
             tiered: bool | None = None) -> tuple[dict, list]:
    """init, chunk, evaluate (and eval_starts) lowered in turn and compiled in threads (evaluate reused
    from the memo), and the names of those the store may keep (program_store.compile_lowered). `tiered`
    (default: on a GPU, in a single-process run) returns once the programs a run starts with are compiled:
    the chunk as a `Tiered` of its builds, still compiling, and with evaluation lanes the evaluation program
    too, whose compile waits until the quick chunk's is done; those store themselves once compiled."""
    platform = devices[0].platform
    # Not across processes: every process of a multi-process run must run the same build of a chunk.
    tiered = platform != "cpu" and jax.process_count() == 1 if tiered is None else tiered
    n = config.train.num_seeds
    keys = jax.ShapeDtypeStruct((n, 2), jnp.uint32)
    total = jax.ShapeDtypeStruct((), jnp.int32)
    hp = (hparams_shape(n, config),) if traced else ()
    pool = ThreadPoolExecutor(4 + tiered)
    # Tracing and lowering are Python, one program at a time whatever the threads; XLA compiles without
    # Python's lock. So each program is lowered in turn, the chunk training starts with (the longest
    # compile) first, and compiles in its thread while the next ones are lowered; the full chunk of a
    # tiered start, needed last, is lowered last.
    # The quick config differs in the actor's sequence loop alone, which only the chunk's updates run: its
    # init, evaluate and eval_starts are the run's own (init already traced for the state's shapes).
    init, chunk, evaluate, eval_starts = jitted_programs(quick_config(config) if tiered else config, devices, traced)
    with kernel_random(tiered):
        state_shape = jax.eval_shape(init, keys, total, *hp)
        chunk_lowered = chunk.lower(state_shape, *hp)
    done, later = {}, {}   # compiled before this returns; compiling on beside the run (tiered)
    if tiered:   # the quick build is never stored: the full one is
        first = pool.submit(lambda lowered: program_store.compile_lowered(lowered, platform, QUICK_CHUNK_OPTIONS)[0],
                            chunk_lowered)
    else:
        done["chunk"] = pool.submit(program_store.compile_lowered, chunk_lowered, platform)
    lowerings = {"init": lambda: init.lower(keys, total, *hp)}
    if names["evaluate"] not in _COMPILED:
        lowerings["evaluate"] = lambda: evaluate.lower(state_shape.agent.actor_average, keys)
    if eval_starts is not None:
        lowerings["eval_starts"] = lambda: eval_starts.lower(keys)
    for name, lower in lowerings.items():
        with kernel_random(tiered):
            lowered = lower()
        if tiered and name == "evaluate" and eval_starts is not None:
            # With evaluation lanes the program evaluates only before a checkpoint and at the end: it
            # compiles after the quick chunk, leaving it the machine's cores.
            later[name] = pool.submit(_compile_and_store, lowered, platform, store, names[name], after=first,
                                      options=BESIDE_TRAINING_OPTIONS)
        else:
            done[name] = pool.submit(program_store.compile_lowered, lowered, platform)
    if tiered:
        full_chunk = jitted_programs(config, devices, traced)[1]
        full = pool.submit(_compile_and_store, full_chunk.lower(state_shape, *hp), platform, store, names["chunk"])
    pool.shutdown(wait=False)   # the chunk (and a later evaluation) compile on while training starts
    compiled = {name: f.result() for name, f in done.items()}
    storable = [name for name, (_, ok) in compiled.items() if ok]
    compiled = {name: c for name, (c, _) in compiled.items()}
    if tiered:
        compiled["chunk"] = Tiered(first, full)
        if "evaluate" in later:
            compiled["evaluate"] = Tiered(later["evaluate"])
    return {"evaluate": _COMPILED.get(names["evaluate"]), **compiled}, storable


# The quick build of a tiered start's chunk: besides `kernel_random`, cuBLAS instead of Triton for its
# matrix products and the replay sequences' loop rolled (`quick_config`), each less for XLA to compile
# and slower to run, for the chunks until the full build is ready.
QUICK_CHUNK_OPTIONS = {"xla_gpu_enable_triton_gemm": False}

# The evaluation program of a tiered start compiles while training runs, where XLA's autotuner would time its
# candidate kernels on the GPU training keeps busy. Without autotuning it compiles in a third to three
# quarters of the time and runs as fast (its matrices are small), so a stop or a checkpoint early in a cold
# run waits less for it; the chunks' pace was the same either way (docs/BENCHMARKS.md, "Start-up").
BESIDE_TRAINING_OPTIONS = {"xla_gpu_autotune_level": 0}


def quick_config(config: Config) -> Config:
    """The config of a tiered start's quick chunk: the actor runs the replay sequences one step per loop
    iteration (agent.sequence_unroll 1). The runner state and the computation are the run's own."""
    return dataclasses.replace(config, agent=dataclasses.replace(config.agent, sequence_unroll=1))


@contextlib.contextmanager
def kernel_random(on: bool):
    """Programs lowered inside draw their random bits on a GPU through one kernel call per draw instead
    of ~120 inlined integer operations each (JAX's `jax_threefry_gpu_kernel_lowering`): bit for bit the
    same numbers, a program that compiles faster and runs slower (XLA no longer fuses the bits into their
    consumers; measured: docs/BENCHMARKS.md, "Start-up"). No effect on a
    CPU. The setting is restored after, so a user's own programs are lowered as they would be."""
    before = jax.config.jax_threefry_gpu_kernel_lowering
    jax.config.update("jax_threefry_gpu_kernel_lowering", on or before)
    try:
        yield
    finally:
        jax.config.update("jax_threefry_gpu_kernel_lowering", before)


def _compile_and_store(lowered, platform: str, store, name: str, after: Future | None = None,
                       options: dict | None = None):
    """A program a `Tiered` start builds beside the run: compiled (with XLA `options`, when given) once
    `after` (when given) is done, then written to the store (when there is one) in this same thread, which
    the process waits for before it exits."""
    if after is not None:
        wait([after])
    compiled, ok = program_store.compile_lowered(lowered, platform, options)
    if store is not None and ok:
        program_store.save(store, name, compiled)
    return compiled


class Tiered:
    """A program of a cold start on a GPU that compiles beside the run (`_compile`): a call waits until
    `first` (a future of the quick build) is compiled and runs it until `full` (a future of the full build,
    if any) is ready; every call after that runs the full build. Both take and return the same arguments and
    compute the same (the same random bits; float rounding aside), so a run may switch between any two
    calls. `quick_calls` counts the calls the quick build ran; `ready_at` is the wall time the first build
    was compiled (None before)."""

    def __init__(self, first: Future, full: Future | None = None):
        self.first, self.full, self.current, self.quick_calls, self.ready_at = first, full, None, 0, None
        first.add_done_callback(lambda _: self._mark_ready())

    def _mark_ready(self) -> None:
        # Also called once a call has the first build: a future wakes the threads waiting for its result
        # before it runs its done callbacks, so the callback may come after that call.
        if self.ready_at is None:
            self.ready_at = time.time()

    @property
    def compiling(self) -> bool:
        """A build is still compiling (a process that ends now waits for it, to store it)."""
        return any(f is not None and not f.done() for f in (self.first, self.full))

    def __call__(self, *args):
        if self.full is not None and self.full.done():
            self.current, self.full = self.full.result(), None   # a failed compile raises here
        elif self.current is None:
            self.current = self.first.result()
            self._mark_ready()
        self.quick_calls += self.full is not None
        return self.current(*args)


def chunk_building(progs: Programs) -> bool:
    """A tiered start's chunk has no build ready yet (compile_programs returned before it)."""
    return isinstance(progs.chunk, Tiered) and progs.chunk.ready_at is None


def building_note(progs: Programs) -> str:
    """What the compile line of a launch adds while a tiered start's chunk still compiles (else '')."""
    return "; the training program compiles on while the run initialises" if chunk_building(progs) else ""


def still_compiling_line(progs: Programs) -> str | None:
    """The line a process prints at its end while builds of a tiered start still compile (the process waits
    for them, to store them for the next launch), else None."""
    compiling = [what for what, p in (("the training program's full build", progs.chunk),
                                      ("the evaluation program", progs.evaluate)) if isinstance(p, Tiered) and p.compiling]
    if not compiling:
        return None
    return (f"{' and '.join(compiling)} {'are' if len(compiling) > 1 else 'is'} still compiling; the process ends "
            "once stored for the next launch (seconds)")


def jitted_programs(config: Config, devices: tuple, traced: bool):
    """init, chunk, evaluate and eval_starts (None without train.eval_alongside) over the seed axis,
    jitted (not yet compiled) for `devices`."""
    trainer = make_trainer(config)
    batched = config.train.num_seeds // len(devices) > 1   # seeds per device
    squeeze = lambda tree: jax.tree.map(lambda x: x[0], tree)  # noqa: E731
    expand = lambda tree: jax.tree.map(lambda x: x[None], tree)  # noqa: E731
    starts = trainer.eval_starts
    if batched:
        init = jax.vmap(trainer.init_total, (0, None, 0) if traced else (0, None))
        chunk = jax.vmap(trainer.chunk)
        evaluate = jax.vmap(trainer.evaluate)
        eval_starts = starts and jax.vmap(starts)
    else:  # hp: () for a plain run (the config's constants), (hp,) with a seed axis when traced
        init = lambda keys, total, *hp: expand(trainer.init_total(keys[0], total, *squeeze(hp)))  # noqa: E731
        chunk = lambda state, *hp: expand(trainer.chunk(squeeze(state), *squeeze(hp)))  # noqa: E731
        evaluate = lambda params, keys: expand(trainer.evaluate(squeeze(params), keys[0]))  # noqa: E731
        eval_starts = starts and (lambda keys: expand(starts(keys[0])))
    for f, name in ((init, "init"), (chunk, "chunk"), (evaluate, "evaluate"), (eval_starts, "eval_starts")):
        if f:  # XLA names a program after its function: jit_chunk, not jit__lambda, in profiles and dumps
            f.__name__ = name
    seeds, whole = PartitionSpec(sharding.SEED_AXIS), PartitionSpec()
    hp = (seeds,) if traced else ()
    return (_over_seeds(init, devices, (seeds, whole, *hp)),
            _over_seeds(chunk, devices, (seeds, *hp), donate_argnums=0),
            _over_seeds(evaluate, devices, (seeds, seeds)),
            eval_starts and _over_seeds(eval_starts, devices, (seeds,)))


def _over_seeds(f, devices: tuple, in_specs: tuple, **jit_kwargs):
    """f jitted for `devices`. On several, shard_map gives each device its block of seeds and runs f
    on it alone (no communication); every output keeps the seed axis, sharded the same way. The one
    place multi-device programs are built, so the partitioner workaround applies to all of them."""
    if len(devices) == 1:
        return jax.jit(f, **jit_kwargs)
    sharding.use_gspmd_partitioner()
    mesh = sharding.SeedPlacement(devices).mesh
    seeds = PartitionSpec(sharding.SEED_AXIS)
    return jax.jit(jax.shard_map(f, mesh=mesh, in_specs=in_specs, out_specs=seeds, check_vma=False),
                   in_shardings=tuple(NamedSharding(mesh, spec) for spec in in_specs),
                   out_shardings=NamedSharding(mesh, seeds), **jit_kwargs)
