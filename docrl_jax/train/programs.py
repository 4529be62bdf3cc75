"""The compiled programs of a run (init, chunk, evaluate; with train.eval_alongside also eval_starts,
the first states of an evaluation's episodes for the chunk's lanes), built for the devices the seeds are split
over and compiled once per process; JAX's persistent compilation cache, which makes the next
process skip compiling; and the program store beside it (docrl_jax.train.program_store), which makes
it skip tracing too.

On one device the programs vmap over the seeds (one seed: the unbatched program on a seed axis of
size 1, because under vmap a per-seed `lax.cond` becomes a select that computes both branches, so
the delayed actor update and the pre-learning phase would cost a full update on every step). On
several devices (train.devices, docrl_jax.sharding) shard_map gives each device its block of seeds;
every input and output keeps the seed axis, sharded over the 'seed' mesh axis.

traced=True (sweeps): init(keys, total, hp) and chunk(state, hp) also take the agent's
hyperparameters (`algorithms.HParams`, one float32 per seed row), so rows that differ only in them
run in one program; the config's own values of those fields are then unused (and normalised away,
so one compilation serves any such values). The evaluation reads no HParams: a sweep and a plain
run of the same shapes share it.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Callable, NamedTuple

import jax
import jax.numpy as jnp
from jax.sharding import NamedSharding, PartitionSpec

from docrl_jax import sharding
from docrl_jax.algorithms.common import HParams, hparams_neutral
from docrl_jax.config import Config
from docrl_jax.train import program_store
from docrl_jax.train.trainer import make_trainer

# ------------------------------------------------------------------ the persistent compilation cache
def default_compile_cache() -> str:
    env = os.environ.get("DOCRL_JAX_COMPILE_CACHE")
    if env:
        return env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "docrl_jax", "jax")


def enable_compile_cache(path: str | None) -> str | None:
    """Turns on JAX's persistent compilation cache in `path` (None: the default; 'off': disabled).
    Returns the folder used, or None. Programs that compile in under a second are not stored."""
    path = default_compile_cache() if path is None else path
    if path.lower() in ("off", "none", ""):
        return None
    os.makedirs(path, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


def device_line() -> str:
    """What the run is on, for the console: 'GPU: NVIDIA H100 80GB HBM3 (1 device)' or a CPU warning."""
    devs = jax.devices()
    if devs[0].platform == "cpu":
        return (f"CPU ({os.cpu_count()} cores): no GPU found, training will be slow; the packaged defaults "
                f"are sized for one GPU (see the ETA)")
    return f"{devs[0].platform.upper()}: {devs[0].device_kind} ({len(devs)} device{'s' if len(devs) > 1 else ''})"


# ------------------------------------------------------------------ the programs
class Programs(NamedTuple):
    init: Callable        # (keys (S, 2), total env steps, [hp]) -> RunnerState stacked over seeds
    chunk: Callable       # (RunnerState, [hp]) -> (RunnerState, chunk metrics); donates its state
    evaluate: Callable    # (actor params stacked over seeds, keys (S, 2)) -> per-seed eval metrics
    state_shape: Any      # the RunnerState's shapes (what a checkpoint is restored into)
    origin: str = "compiled"  # "compiled" in this process, or "loaded" from the program store
    eval_starts: Callable | None = None  # keys (S, 2) -> the evaluation lanes' first states (train.eval_alongside)

    def evaluation_ready(self) -> bool:
        """Whether evaluate and eval_starts are there (with train.eval_alongside they are built while
        the first chunks run: `Pending`)."""
        return all(p.ready() for p in (self.evaluate, self.eval_starts) if isinstance(p, Pending))


def program_config(config: Config, traced: bool = False) -> Config:
    """The config with every field that does not shape the compiled programs set to a constant, so
    runs that differ only in them (name, seeds, length, cadences; with `traced` the HParams) share
    one compilation: the run length is a runner-state field and the seed keys are arguments."""
    train = dataclasses.replace(config.train, seed=0, total_env_steps=1, eval_every=1, checkpoint_every=1,
                                keep_checkpoints=1, devices=0, eval_trained_actor=False,
                                eval_every_minutes=1.0, checkpoint_every_minutes=1.0, video_every=0)
    agent = hparams_neutral(config.agent) if traced else config.agent
    return dataclasses.replace(config, name="run", train=train, agent=agent)


def hparams_shape(num_rows: int, config: Config):
    """Shapes of the traced programs' `hp` argument: one float32 per seed row and HParams leaf."""
    return jax.tree.map(lambda _: jax.ShapeDtypeStruct((num_rows,), jnp.float32),
                        HParams.from_agent_config(config.agent))


# The one memo of compiled programs, by their store entry names: a resume or a second run of the
# same shapes in one process compiles nothing.
_COMPILED: dict = {}
# The programs an evaluation alongside training needs (train.eval_alongside): obtained after init and
# chunk, beside the first chunks, so a launch starts training without waiting for them.
DEFERRED = ("evaluate", "eval_starts")


class Pending:
    """A program still being compiled or loaded in a background thread. Called, it waits for the
    program and runs it; `ready()` says whether it is there, without waiting. A failure to build it
    is raised by the call."""

    def __init__(self, job: Future, what: str):
        self._job, self.what = job, what

    def ready(self) -> bool:
        return self._job.done()

    def __call__(self, *args):
        return self._job.result()[self.what](*args)


def compile_programs(config: Config, devices: tuple | None = None, traced: bool = False) -> tuple[Programs, float]:
    """The run's programs for `devices` (the tuple from `sharding.seed_devices`; None resolves
    train.devices here, for callers without a run's placement). Memoised in the process; else loaded
    from the program store when an earlier launch built them (docrl_jax.train.program_store: no env
    build, no tracing); else compiled ahead of time, several at once in threads (XLA compiles them in
    parallel), and stored (in a background thread). With train.eval_alongside, evaluate and
    eval_starts are `Pending`: they are built after init and chunk, while training runs, and the
    first evaluation begins once they are there (`Programs.evaluation_ready`). Returns the programs
    and the seconds this call spent on those it waited for (0 when memoised)."""
    devices = sharding.seed_devices(config.train)[0] if devices is None else devices
    config = program_config(config, traced)
    # The store's entry names describe the programs, so they key the memo too: the evaluation alone
    # (a sweep and a plain run of the same shapes share it) and the whole set.
    names = store_names(config, devices, traced)
    whole = tuple(names.values())
    if whole in _COMPILED:
        return _COMPILED[whole], 0.0
    t0 = time.time()
    builder = _Builder(config, devices, traced, names)
    later = [what for what in DEFERRED if what in names] if config.train.eval_alongside else []
    got, origin = builder.obtain([what for what in names if what not in later])
    state_shape = builder.state_shape(got["init"])
    if later:
        pool = ThreadPoolExecutor(1, thread_name_prefix="docrl_jax evaluation programs")
        job = pool.submit(lambda: builder.obtain(later)[0])
        pool.shutdown(wait=False)   # the thread builds them and ends; the process waits for it at exit
        got.update({what: Pending(job, what) for what in later})
    _COMPILED[names["evaluate"]] = got["evaluate"]
    _COMPILED[whole] = Programs(got["init"], got["chunk"], got["evaluate"], state_shape, origin, got.get("eval_starts"))
    return _COMPILED[whole], time.time() - t0


def store_names(config: Config, devices: tuple, traced: bool = False) -> dict[str, str]:
    """The program store's entry names of init, chunk and evaluate (and eval_starts, with
    train.eval_alongside) for this config and devices."""
    config = program_config(config, traced)
    # The evaluation's programs read no HParams and not how evaluations run: sweeps and plain runs, with
    # evaluations alongside training or not, share them.
    evaluation = program_config(dataclasses.replace(config, train=dataclasses.replace(config.train, eval_alongside=False)),
                                True)
    described = {"init": (config, traced), "chunk": (config, traced), "evaluate": (evaluation, None)}
    if config.train.eval_alongside:
        described["eval_starts"] = (evaluation, None)
    return {what: program_store.key(repr(c), program_store.device_key(devices), kind, what)
            for what, (c, kind) in described.items()}


class _Builder:
    """Obtains some of a run's programs: from the memo (the evaluation), the program store, or the
    compiler. The env is built and the functions traced only when something must be compiled, at
    most once for all the run's programs."""

    def __init__(self, config: Config, devices: tuple, traced: bool, names: dict[str, str]):
        self.config, self.devices, self.traced, self.names = config, devices, traced, names
        self.store = program_store.folder()
        self._jitted = self._shape = None

    def obtain(self, which: list[str]) -> tuple[dict, str]:
        """{name: program} for `which`, and "loaded" (every one not memoised came from the store) or
        "compiled"."""
        got = {w: _COMPILED[self.names[w]] for w in which if w == "evaluate" and self.names[w] in _COMPILED}
        todo = {w: self.names[w] for w in which if w not in got}
        loaded = _load(self.store, todo, self.devices) if self.store is not None and todo else None
        if loaded is not None or not todo:
            return {**got, **(loaded or {})}, "loaded"
        compiled, storable = self._compile(list(todo))
        if self.store is not None and storable:  # written beside the run's start, not before it
            program_store.save_in_background(self.store, {todo[w]: compiled[w] for w in storable})
        return {**got, **compiled}, "compiled"

    def state_shape(self, init=None):
        """The runner state's shapes, as the init program returns them (what a checkpoint is restored
        into and the chunk takes): from a built `init`, else by tracing it."""
        if self._shape is None:
            self._shape = (jax.tree.map(lambda s: jax.ShapeDtypeStruct(s.shape, s.dtype), init.out_info)
                           if init is not None else jax.eval_shape(self._functions()[0], *self._init_args()))
        return self._shape

    def _functions(self):
        if self._jitted is None:
            self._jitted = _jitted(self.config, self.devices, self.traced)
        return self._jitted

    def _init_args(self) -> tuple:
        n = self.config.train.num_seeds
        hp = (hparams_shape(n, self.config),) if self.traced else ()
        return jax.ShapeDtypeStruct((n, 2), jnp.uint32), jax.ShapeDtypeStruct((), jnp.int32), *hp

    def _compile(self, which: list[str]) -> tuple[dict, list]:
        """`which` traced and compiled, in threads, and the names of those the store may keep
        (program_store.compile_lowered)."""
        init, chunk, evaluate, eval_starts = self._functions()
        keys, total, *hp = self._init_args()
        lowerings = {"init": lambda: init.lower(keys, total, *hp),
                     "chunk": lambda: chunk.lower(self.state_shape(), *hp),
                     "evaluate": lambda: evaluate.lower(self.state_shape().agent.actor_average, keys),
                     "eval_starts": lambda: eval_starts.lower(keys)}
        self.state_shape()   # traced once, before the threads that read it
        with ThreadPoolExecutor(len(which)) as pool:
            done = {w: pool.submit(program_store.compile_lowered, lowerings[w], self.devices[0].platform)
                    for w in which}
            compiled = {w: f.result() for w, f in done.items()}
        return {w: c for w, (c, _) in compiled.items()}, [w for w, (_, ok) in compiled.items() if ok]


def _load(store, names: dict, devices) -> dict | None:
    """The programs `names` ({name: store entry}) from the store, loaded in threads, or None if any is
    missing."""
    with ThreadPoolExecutor(len(names)) as pool:
        done = {what: pool.submit(program_store.load, store, name, devices) for what, name in names.items()}
        loaded = {what: f.result() for what, f in done.items()}
    return loaded if all(p is not None for p in loaded.values()) else None


def _jitted(config: Config, devices: tuple, traced: bool):
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
