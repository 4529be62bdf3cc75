"""Compiled programs kept on disk between launches, in a folder beside JAX's compilation cache.

JAX's cache spares a second launch the compiler, not the tracing and lowering of the programs
(seconds for an MJX training step) nor the cache lookup itself. This store keeps the executables
(`jax.experimental.serialize_executable`), so a launch whose programs were built before loads them
and runs: no env build, no tracing, no lowering.

An entry's key is a digest of everything that shapes its program: the program's config, the
devices, the versions of the packages that trace and compile it, the XLA and JAX settings that
change code generation, and the bytes of docrl_jax's own source and scenes (an edited checkout
never loads a stale program). A missing, unreadable or incompatible entry is a miss: the caller
compiles as usual and the entry is written again. Entries are pickles, trusted like JAX's own
cache: point the cache only at folders you write.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import os
import pickle
import tempfile
import threading
from pathlib import Path
from typing import Callable

import jax
from jax.experimental import serialize_executable

from docrl_jax.resources import resource_dir, versions

FORMAT = 1
FOLDER = "programs"
MAX_ENTRIES = 60   # the most recently used entries kept (three per config and checkout)
# Packages whose version changes the traced or compiled program.
PACKAGES = ("jax", "jaxlib", "jax-cuda12-plugin", "jax-cuda12-pjrt", "jax-cuda13-plugin", "jax-cuda13-pjrt",
            "mujoco", "mujoco-mjx", "flax", "optax", "chex", "numpy")
# JAX settings that change what a traced function lowers to.
JAX_FLAGS = ("jax_enable_x64", "jax_default_matmul_precision", "jax_default_prng_impl", "jax_threefry_partitionable",
             "jax_numpy_dtype_promotion", "jax_use_shardy_partitioner")


def folder() -> Path | None:
    """The store of this process: `programs/` inside JAX's compilation cache folder; None when the
    cache is off (docrl_jax.train.programs.enable_compile_cache) or the run spans several processes
    (each holds only its part of a program, and they may share one folder: they compile)."""
    cache = jax.config.jax_compilation_cache_dir
    return Path(cache) / FOLDER if cache and jax.process_count() == 1 else None


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """sha256 of docrl_jax's Python files and scene files, names and bytes."""
    h = hashlib.sha256()
    package, assets = Path(__file__).resolve().parents[1], resource_dir("assets")
    files = [(p.relative_to(package).as_posix(), p) for p in sorted(package.rglob("*.py"))]
    files += [(f"assets/{p.name}", p) for p in sorted(assets.glob("*.xml"))]
    for name, path in files:
        h.update(name.encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


def key(*parts) -> str:
    """The entry name of a program described by `parts` (reprs of its config, devices, role)."""
    settings = {name: str(getattr(jax.config, name, None)) for name in JAX_FLAGS}
    described = repr((FORMAT, parts, versions(PACKAGES), settings, os.environ.get("XLA_FLAGS", ""), source_digest()))
    return hashlib.sha256(described.encode()).hexdigest()[:40]


def device_key(devices) -> tuple:
    """What of the devices a compiled program is bound to."""
    return tuple((d.platform, d.device_kind, d.id, d.process_index) for d in devices)


def load(store: Path, name: str, devices) -> jax.stages.Compiled | None:
    """The stored program `name` loaded onto `devices`, or None when absent or unusable."""
    path = store / f"{name}.bin"
    if devices[0].platform == "cpu" and not _cpu_kernels_ready():
        return None
    try:
        with open(path, "rb") as f:
            fmt, payload, in_tree, out_tree = pickle.load(f)
        if fmt != FORMAT:
            return None
        program = serialize_executable.deserialize_and_load(payload, in_tree, out_tree, backend=devices[0].client,
                                                            execution_devices=list(devices))
        os.utime(path)  # recently used: kept by the pruning in `save`
        return program
    except FileNotFoundError:
        return None
    except Exception:  # noqa: BLE001  a damaged or foreign entry is a miss; the caller compiles and rewrites it
        return None


@functools.lru_cache(maxsize=1)
def _cpu_kernels_ready() -> bool:
    """Registers the CPU's LAPACK kernels, which JAX otherwise registers while lowering a linear
    algebra op: a loaded program that calls one (MJX's solves) would jump to an unset kernel. False
    (no loading on the CPU) if this JAX has no such hook."""
    try:
        from jax._src.lax import linalg
        linalg.initialize_lapack()
        return True
    except (ImportError, AttributeError):
        return False


_thread = threading.local()


def _on_event(event: str, **_) -> None:
    if event == "/jax/compilation_cache/cache_hits":
        _thread.cache_hit = True


@functools.lru_cache(maxsize=1)
def _listen() -> None:
    jax.monitoring.register_event_listener(_on_event)


def compile_lowered(lower: Callable[[], jax.stages.Lowered], platform: str) -> tuple[jax.stages.Compiled, bool]:
    """`lower().compile()`, and whether the executable may be stored. On the CPU only one the
    compiler built in this process may: XLA's CPU executable, once loaded from JAX's persistent
    cache, serialises without some of its functions and would fail when loaded again."""
    _listen()
    _thread.cache_hit = False
    compiled = lower().compile()
    return compiled, not (platform == "cpu" and _thread.cache_hit)


def save(store: Path, name: str, compiled: jax.stages.Compiled) -> bool:
    """Writes `compiled` as entry `name` (atomically: a reader sees the old entry or the whole new
    one). Returns False when the program cannot be serialised or the folder is not writable: the
    store only saves time, so its failures never stop a run."""
    tmp = None
    try:
        payload, in_tree, out_tree = serialize_executable.serialize(compiled)
        store.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=store, prefix=f".{name}.", suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            pickle.dump((FORMAT, payload, in_tree, out_tree), f, protocol=pickle.HIGHEST_PROTOCOL)
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
