"""Compiled programs kept on disk between launches, in a folder beside JAX's compilation cache.

JAX's cache spares a second launch the compiler, not the tracing and lowering of the programs
(seconds for an MJX training step) nor the cache lookup itself. This store keeps the executables
(`jax.experimental.serialize_executable`), so a launch whose programs were built before loads them
and runs: no env build, no tracing, no lowering.

An entry's key is a digest of everything that shapes its program: the program's config, the
devices, the versions of the packages that trace and compile it, the XLA and JAX settings that
change code generation, and the bytes of docrl_jax's own source and scenes (an edited checkout
never loads a stale program). A missing, unreadable or incompatible entry is a miss: the caller
compiles as usual and the entry is written again.

Entries are pickles and JAX's cache holds machine code: loading either runs what it holds. A cache
folder, the store's folder or an entry that another user owns or that its group or others may write
(a cache on a shared lab file system) is therefore never read: one warning line names it and the run
compiles (`refusal`). The folders this module creates only their owner may write.

JAX may pass a program's larger constants (closed-over arrays: the MJX model, the scene's solids) as
hidden arguments rather than inside the executable (`jax_use_simplified_jaxpr_constants`, off by
default in JAX 0.10 and 0.11; under it every env program has dozens to hundreds). JAX's own
serialisation refuses such programs, so an entry keeps their values beside the executable and a
load hands them back; an entry whose executable expects other inputs than it carries is a miss.

A launch starts loading its entries early (`prefetch`), before it imports MJX, Flax and Orbax:
loading an executable runs in XLA without Python's lock, so the two overlap. An entry therefore
keeps the executable apart from its input and output trees, whose classes (MJX's `Data`) only the
later imports provide.

This module imports nothing heavier than JAX and the config, so the command line can start that
prefetch first.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import os
import pickle
import stat
import sys
import tempfile
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING

import jax

from docrl_jax import sharding
from docrl_jax.train import jax_internals
from docrl_jax.resources import resource_dir, versions

if TYPE_CHECKING:
    from docrl_jax.config import Config

# 3: (FORMAT, (executable, flat argument info, no_kwargs, hoisted constants), pickled (in_tree, out_tree));
# 2 had no constants; 1 pickled the trees beside the executable.
FORMAT = 3
FOLDER = "programs"
MAX_ENTRIES = 60   # the most recently used entries kept (three per config and checkout)
# Packages whose version changes the traced or compiled program.
PACKAGES = ("jax", "jaxlib", "jax-cuda12-plugin", "jax-cuda12-pjrt", "jax-cuda13-plugin", "jax-cuda13-pjrt",
            "mujoco", "mujoco-mjx", "flax", "optax", "chex", "numpy")
# JAX settings that change what a traced function lowers or compiles to.
JAX_FLAGS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_default_prng_impl", "jax_threefry_partitionable",
             "jax_threefry_gpu_kernel_lowering", "jax_numpy_dtype_promotion", "jax_use_shardy_partitioner",
             "jax_use_simplified_jaxpr_constants", "jax_embedded_constants_max_bytes", "jax_disable_most_optimizations")


# ------------------------------------------------------------------ the persistent compilation cache
def default_compile_cache() -> str:
    env = os.environ.get("DOCRL_JAX_COMPILE_CACHE")
    if env:
        return env
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "docrl_jax", "jax")


def enable_compile_cache(path: str | None) -> str | None:
    """Turns on JAX's persistent compilation cache in `path` (None: the default; 'off': disabled).
    Returns the folder used, or None; also None, with a warning line, for a folder others may write
    (`refusal`). Programs that compile in under a second are not stored."""
    path = default_compile_cache() if path is None else path
    if path.lower() in ("off", "none", ""):
        return None
    os.makedirs(path, mode=0o700, exist_ok=True)
    if _refused(path, os.stat(path)):
        return None
    jax.config.update("jax_compilation_cache_dir", path)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path


# ------------------------------------------------------------------ the store
def folder() -> Path | None:
    """The store of this process: `programs/` inside JAX's compilation cache folder; None when the
    cache is off (enable_compile_cache) or the run spans several processes
    (each holds only its part of a program, and they may share one folder: they compile)."""
    cache = jax.config.jax_compilation_cache_dir
    if not cache or jax.process_count() > 1:
        return None
    store = Path(cache) / FOLDER
    try:
        return None if _refused(store, store.stat()) else store
    except OSError:  # not made yet: `save` makes it
        return store


# ------------------------------------------------------------------ whose files are loaded
def refusal(info: os.stat_result) -> str | None:
    """Why a cache folder or entry with this `os.stat` must not be loaded, or None: another user owns
    it, or its group or every user may write it (they could place a pickle or an executable there)."""
    me = _current_uid()
    if me is not None and info.st_uid != me:
        return f"owned by another user (uid {info.st_uid})"
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by {'others' if info.st_mode & stat.S_IWOTH else 'its group'}"
    return None


def _current_uid() -> int | None:
    return os.getuid() if hasattr(os, "getuid") else None   # no owners to compare where there are no uids


_warned: set = set()


def _refused(path, info: os.stat_result) -> bool:
    """True, after one warning line on stderr (once per path), when `refusal` refuses `path`."""
    reason = refusal(info)
    if reason is not None and str(path) not in _warned:
        _warned.add(str(path))
        sys.stderr.write(f"warning: compilation cache {path} is {reason}: not loaded, the programs are compiled; "
                         f"use a folder only you can write (--compile-cache DIR, DOCRL_JAX_COMPILE_CACHE, "
                         f"or chmod go-w)\n")
    return reason is not None


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """sha256 of docrl_jax's Python files, scene files and packaged tanks, names and bytes."""
    h = hashlib.sha256()
    package, assets = Path(__file__).resolve().parents[1], resource_dir("assets")
    files = [(p.relative_to(package).as_posix(), p) for p in sorted(package.rglob("*.py"))]
    files += [(f"assets/{p.name}", p) for p in sorted(assets.glob("*.xml"))]
    files += [(f"assets/tanks/{p.name}", p) for p in sorted((assets / "tanks").glob("*")) if p.is_file()]
    for name, path in files:
        h.update(name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def tank_digest(config: Config) -> str:
    """sha256 of the files that the run's env.tank names (a file, or every file of a folder; a bare
    name or 'gallery' is a packaged tank, in `source_digest`): the programs hold the tanks' solids as
    constants, so an edited tank file is a miss."""
    spec = config.env.env_kwargs().get("tank")
    if spec is None:
        return ""
    path = Path(str(spec)).expanduser()
    h = hashlib.sha256()
    for file in sorted(path.iterdir()) if path.is_dir() else [path]:
        if file.is_file():
            h.update(file.name.encode() + b"\0" + file.read_bytes())
    return h.hexdigest()


def key(*parts) -> str:
    """The entry name of a program described by `parts` (reprs of its config, devices, role)."""
    settings = {name: str(getattr(jax.config, name, None)) for name in JAX_FLAGS}
    described = repr((FORMAT, parts, versions(PACKAGES), settings, os.environ.get("XLA_FLAGS", ""), source_digest()))
    return hashlib.sha256(described.encode()).hexdigest()[:40]


def device_key(devices) -> tuple:
    """What of the devices a compiled program is bound to."""
    return tuple((d.platform, d.device_kind, d.id, d.process_index) for d in devices)


def program_config(config: Config, traced: bool = False) -> Config:
    """The config with every field that does not shape the compiled programs set to a constant, so
    runs that differ only in them (name, seeds, length, cadences; with `traced` the HParams) share
    one compilation: the run length is a runner-state field and the seed keys are arguments."""
    train = dataclasses.replace(config.train, seed=0, total_env_steps=1, eval_every=1, checkpoint_every=1,
                                keep_checkpoints=1, devices=0, eval_trained_actor=False,
                                eval_every_minutes=1.0, checkpoint_every_minutes=1.0, video_every=0)
    agent = config.agent
    if traced:
        from docrl_jax.algorithms.common import hparams_neutral  # sweeps only: Flax is not needed before
        agent = hparams_neutral(agent)
    return dataclasses.replace(config, name="run", train=train, agent=agent)


# What of the agent the evaluation's programs read: the actor that acts (`Agent.act`), and whether its carry flows.
EVALUATED_AGENT_FIELDS = ("algo", "actor", "actor_hidden", "frames", "memory")


def evaluation_config(config: Config) -> Config:
    """The config as far as it shapes the evaluation's programs (evaluate, eval_starts). They read no
    HParams, nothing of the critics, targets or replay, and not how evaluations run: sweeps and plain runs,
    with evaluations alongside training or not, and runs that differ only in their learner share them."""
    from docrl_jax.config import AgentConfig, ReplayConfig
    agent = AgentConfig(**{k: getattr(config.agent, k) for k in EVALUATED_AGENT_FIELDS})
    return program_config(dataclasses.replace(config, agent=agent, replay=ReplayConfig(),
                                              train=dataclasses.replace(config.train, eval_alongside=False)), True)


def store_names(config: Config, devices: tuple, traced: bool = False) -> dict[str, str]:
    """The entry names of init, chunk and evaluate (and eval_starts, with train.eval_alongside) for
    this config and devices."""
    config = program_config(config, traced)
    evaluation = evaluation_config(config)
    described = {"init": (config, traced), "chunk": (config, traced), "evaluate": (evaluation, None)}
    if config.train.eval_alongside:
        described["eval_starts"] = (evaluation, None)
    tanks = tank_digest(config)
    return {what: key(repr(c), device_key(devices), kind, what, tanks) for what, (c, kind) in described.items()}


# The loads `prefetch` started: a future of {entry path: future of its `_read`}, set once the
# entries are named (which needs the backend, so it runs in the background too).
_prefetched: Future | None = None


def prefetch(config: Config) -> None:
    """Starts loading the stored programs of `config` (a single-process run's) in background threads
    and returns at once. The first `load` of each entry then takes the loaded executable instead of
    reading it again. A launch calls this before its heavy imports (MuJoCo and MJX, Flax, Orbax: ~2.5
    s on a GPU machine), which the loads (~3 s) overlap. The threads initialise JAX's backend, so a
    multi-process run must not call it before jax.distributed.initialize (it then has no store).
    Failures (an impossible train.devices, no store, a missing entry) only leave nothing prefetched:
    the launch reports or handles them itself."""
    def name_and_start() -> dict:
        devices = sharding.seed_devices(config.train)[0]
        store = folder()
        if store is None:
            return {}
        paths = [store / f"{name}.bin" for name in store_names(config, devices).values()]
        pool = ThreadPoolExecutor(len(paths), thread_name_prefix="docrl_jax program prefetch")
        started = {str(path): pool.submit(_read, path, devices) for path in paths}
        pool.shutdown(wait=False)
        return started
    global _prefetched
    pool = ThreadPoolExecutor(1, thread_name_prefix="docrl_jax program prefetch")
    _prefetched = pool.submit(name_and_start)
    pool.shutdown(wait=False)


def _read(path: Path, devices) -> tuple:
    """The entry at `path` with its executable loaded onto `devices` (the seconds-long part, which
    XLA runs without Python's lock): ((unloaded executable, flat argument info, no_kwargs, hoisted
    constants), the pickled trees): `jax_internals.unpack`, split from the rest of the load because
    that needs the trees; the store's key holds JAX's version, and anything that fails here is a miss."""
    if devices[0].platform == "cpu" and not jax_internals.cpu_kernels_ready():
        raise LookupError("no loading on this CPU")
    with open(path, "rb") as f:
        if _refused(path, os.fstat(f.fileno())):   # the file opened, whatever is at `path` later
            raise LookupError("an entry others may have written")
        fmt, payload, trees = pickle.load(f)
    if fmt != FORMAT:
        raise LookupError(f"entry format {fmt}")
    return jax_internals.unpack(payload, devices), trees


def _take_prefetched(path: Path):
    """The future of `path`'s prefetched read, or None (nothing prefetched, or not this entry)."""
    if _prefetched is None or _prefetched.exception() is not None:
        return None
    return _prefetched.result().pop(str(path), None)


def load(store: Path, name: str, devices) -> jax.stages.Compiled | None:
    """The stored program `name` loaded onto `devices`, or None when absent or unusable."""
    path = store / f"{name}.bin"
    try:
        early = _take_prefetched(path)
        entry = early.result() if early is not None else _read(path, devices)
        parts, trees = entry
        program = jax_internals.callable_program(parts, *pickle.loads(trees))
        with contextlib.suppress(OSError):
            os.utime(path)  # recently used: kept by the pruning in `save`
        return program
    except Exception:  # noqa: BLE001  a missing, damaged or foreign entry is a miss; the caller compiles and rewrites it
        return None


_thread = threading.local()


def _on_event(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _thread.cache_hit = True


@functools.lru_cache(maxsize=1)
def _listen() -> None:
    jax.monitoring.register_event_listener(_on_event)


def compile_lowered(lowered: jax.stages.Lowered, platform: str, options: dict | None = None
                    ) -> tuple[jax.stages.Compiled, bool]:
    """`lowered.compile()` (with XLA `options` when given), and whether the executable may be stored. On
    the CPU only one the compiler built in this process may: XLA's CPU executable, once loaded from JAX's
    persistent cache, serialises without some of its functions and would fail when loaded again."""
    _listen()
    _thread.cache_hit = False
    compiled = lowered.compile(compiler_options=options) if options else lowered.compile()
    return compiled, not (platform == "cpu" and _thread.cache_hit)


def save(store: Path, name: str, compiled: jax.stages.Compiled) -> bool:
    """Writes `compiled` as entry `name` (atomically: a reader sees the old entry or the whole new
    one). Returns False when the program cannot be serialised or the folder is not writable: the
    store only saves time, so its failures never stop a run."""
    tmp = None
    try:
        payload, in_tree, out_tree = jax_internals.dumps(compiled)
        store.mkdir(mode=0o700, parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=store, prefix=f".{name}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            pickle.dump((FORMAT, payload, pickle.dumps((in_tree, out_tree), protocol=pickle.HIGHEST_PROTOCOL)), f,
                        protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, store / f"{name}.bin")
        tmp = None
    except Exception:  # noqa: BLE001  (serialisation, pickling or the file system: the run goes on)
        return False
    finally:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
    _prune(store)
    return True


def save_in_background(store: Path, programs: dict) -> threading.Thread:
    """Saves {entry name: compiled program} in a thread, so a fresh launch starts training while its
    programs are written; the thread is not a daemon, so the process exits only once they are."""
    thread = threading.Thread(target=lambda: [save(store, name, p) for name, p in programs.items()],
                              name="docrl_jax program store")
    thread.start()
    return thread


def _prune(store: Path) -> None:
    """Removes all but the MAX_ENTRIES most recently used entries (an edited checkout or another
    config leaves its old programs behind). Other processes may prune the same folder at once."""
    def used(path: Path) -> float:
        try:
            return path.stat().st_mtime
        except OSError:
            return 0.0
    for path in sorted(store.glob("*.bin"), key=used, reverse=True)[MAX_ENTRIES:]:
        with contextlib.suppress(OSError):
            path.unlink()
