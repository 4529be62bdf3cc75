"""The one home of the private JAX names the program store needs (docrl_jax/train/program_store.py): how a
compiled program is written to bytes with the constants JAX hoists out of it, read back onto devices and
made callable again, and the CPU's LAPACK kernels registered before a loaded program calls them.

JAX's public `serialize_executable.serialize` refuses programs with hoisted constants (every env program
under `jax_use_simplified_jaxpr_constants`), so these functions use the pickler it is built on and the
compiled object's fields. A JAX upgrade may move any of them: `missing()` names what this JAX lacks, and
tests/train/test_jax_internals.py fails naming it (the store itself then only misses: every launch compiles).
"""

from __future__ import annotations

import functools
import io

import jax
import numpy as np
from jax.experimental import serialize_executable

# (what, how it is found) of every private name used below
INTERNALS = (
    ("serialize_executable._JaxPjrtPickler", lambda c: serialize_executable._JaxPjrtPickler),
    ("serialize_executable._JaxPjrtUnpickler", lambda c: serialize_executable._JaxPjrtUnpickler),
    ("Compiled._executable._unloaded_executable", lambda c: c._executable._unloaded_executable),
    ("Compiled._params.const_args", lambda c: c._params.const_args),
    ("Compiled._no_kwargs", lambda c: c._no_kwargs),
    ("loaded executable ._all_args_info.in_avals", lambda c: c._executable._unloaded_executable.load()._all_args_info.in_avals),
    ("loaded executable .shard_const_args", lambda c: c._executable._unloaded_executable.load().shard_const_args),
    ("jax._src.lax.linalg.initialize_lapack", lambda c: _lapack_hook()),
)


def missing() -> list[str]:
    """The private names of INTERNALS this JAX lacks (on a small program compiled here); [] when all are there."""
    compiled = jax.jit(lambda x: x + np.arange(3, dtype=np.float32)).lower(np.zeros(3, np.float32)).compile()
    gone = []
    for what, find in INTERNALS:
        try:
            find(compiled)
        except (AttributeError, ImportError):
            gone.append(what)
    return gone


def dumps(compiled: jax.stages.Compiled) -> tuple[bytes, object, object]:
    """(payload, in_tree, out_tree) of `compiled`, its hoisted constants kept as NumPy arrays in the payload.
    Raises ValueError if the program cannot be kept (a closed-over mutable array, a constant NumPy cannot hold
    such as a PRNG key array)."""
    unloaded = getattr(compiled._executable, "_unloaded_executable", None)
    if unloaded is None:
        raise ValueError("this executable cannot be serialised")
    if getattr(unloaded, "mut", None) and unloaded.mut.in_mut:
        raise ValueError("a closed-over mutable array")
    consts = [np.asarray(c) for c in compiled._params.const_args]
    if any(c.dtype == object for c in consts):
        raise ValueError("a constant NumPy cannot hold")
    args_info_flat, in_tree = jax.tree.flatten(compiled.args_info)
    return pack((unloaded, args_info_flat, compiled._no_kwargs, consts)), in_tree, compiled.out_tree


def pack(parts: tuple) -> bytes:
    """(unloaded executable, flat argument info, no_kwargs, constants) as bytes."""
    with io.BytesIO() as f:
        serialize_executable._JaxPjrtPickler(f).dump(parts)
        return f.getvalue()


def unpack(payload: bytes, devices) -> tuple:
    """`pack`'s parts, the executable loaded onto `devices` (the seconds-long part, which XLA runs without
    Python's lock): the first half of `serialize_executable.deserialize_and_load`."""
    return serialize_executable._JaxPjrtUnpickler(io.BytesIO(payload), devices[0].client, list(devices)).load()


def callable_program(parts: tuple, in_tree, out_tree) -> jax.stages.Compiled:
    """The second half of `deserialize_and_load`: `unpack`'s parts as a program to call, the constants it takes
    as hidden arguments placed as it expects them. LookupError when its executable takes other inputs than
    the parts carry (a program called with them would fail only at its first call)."""
    unloaded, args_info_flat, no_kwargs, consts = parts
    executable = unloaded.load()
    expected = getattr(getattr(executable, "_all_args_info", None), "in_avals", None)
    if expected is None or len(expected) != len(consts) + len(args_info_flat):
        raise LookupError("the executable's inputs are not the entry's")
    if any((a.shape, a.dtype) != (c.shape, c.dtype) for a, c in zip(expected, consts)):
        raise LookupError("the entry's constants are not the executable's")
    return jax.stages.Compiled(executable, executable.shard_const_args(consts) if consts else [],
                               in_tree.unflatten(args_info_flat), out_tree, no_kwargs=no_kwargs)


def _lapack_hook():
    from jax._src.lax import linalg
    return linalg.initialize_lapack


@functools.lru_cache(maxsize=1)
def cpu_kernels_ready() -> bool:
    """Registers the CPU's LAPACK kernels, which JAX otherwise registers while lowering a linear algebra
    op: a loaded program that calls one (MJX's solves) would jump to an unset kernel. False (no loading on
    the CPU) if this JAX has no such hook."""
    try:
        _lapack_hook()()
        return True
    except (ImportError, AttributeError):
        return False
