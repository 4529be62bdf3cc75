"""The program store: a later launch loads the compiled programs an earlier one stored, without
building the env or tracing, and they compute exactly what the compiled ones do; a damaged entry is
a miss; entry names follow what shapes the programs and nothing else."""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.train import program_store, programs

from _trainer_common import easy_config


def _leaves_equal(a, b) -> bool:
    return jax.tree.structure(a) == jax.tree.structure(b) and all(
        np.array_equal(np.asarray(x), np.asarray(y), equal_nan=True) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def test_stored_programs_load_without_tracing_and_compute_the_same(tmp_path, monkeypatch):
    config = easy_config()
    devices = (jax.devices()[0],)
    compiled, _ = programs.compile_programs(config, devices)   # compiled in this process (or memoised)
    names = program_store.store_names(config, devices)
    for what, name in names.items():
        assert program_store.save(tmp_path, name, getattr(compiled, what)), what

    # A new launch: nothing in memory, the store in place, and tracing impossible.
    monkeypatch.setattr(programs, "_COMPILED", {})
    monkeypatch.setattr(program_store, "folder", lambda: tmp_path)
    monkeypatch.setattr(programs, "make_trainer", lambda *a: pytest.fail("the env was built: not loaded"))
    loaded, _ = programs.compile_programs(easy_config(train__seed=5, train__total_env_steps=48000), devices)
    assert loaded.origin == "loaded" and compiled.origin == "compiled"
    # Whatever constants JAX passes the programs as hidden arguments come back with them.
    assert all(len(getattr(loaded, w)._params.const_args) == len(getattr(compiled, w)._params.const_args) for w in names)
    assert jax.tree.structure(loaded.state_shape) == jax.tree.structure(compiled.state_shape)
    assert jax.tree.leaves(loaded.state_shape) == jax.tree.leaves(compiled.state_shape)

    # A launch's prefetch (the command line starts it before the heavy imports): its loads are the
    # ones used, here with the entries deleted once they are loaded.
    monkeypatch.setattr(programs, "_COMPILED", {})
    monkeypatch.setattr(program_store, "_prefetched", None)
    program_store.prefetch(easy_config(train__seed=7))
    assert all(f.result() is not None for f in program_store._prefetched.result().values())
    for name in names.values():
        (tmp_path / f"{name}.bin").unlink()
    prefetched, _ = programs.compile_programs(easy_config(train__seed=7), devices)
    assert prefetched.origin == "loaded" and not program_store._prefetched.result()  # each taken once

    keys = jnp.stack([jax.random.PRNGKey(3)])
    total = jnp.asarray(4000, jnp.int32)
    results = []
    for progs in (compiled, loaded, prefetched):
        state = progs.init(keys, total)
        ev = progs.evaluate(state.agent.actor_average, keys)
        state, m = progs.chunk(state)
        results.append((jax.device_get(state), jax.device_get(m), jax.device_get(ev)))
    assert _leaves_equal(results[0], results[1]) and _leaves_equal(results[0], results[2])


def test_damaged_entries_are_misses_and_old_ones_are_pruned(tmp_path, monkeypatch):
    devices = (jax.devices()[0],)
    f = jax.jit(lambda x: jnp.sin(x) * 2.0).lower(jnp.ones(3)).compile()
    assert program_store.save(tmp_path, "a", f)
    assert np.allclose(program_store.load(tmp_path, "a", devices)(jnp.ones(3)), 2 * np.sin(1.0))
    assert program_store.load(tmp_path, "absent", devices) is None
    (tmp_path / "a.bin").write_bytes(b"not a program")
    assert program_store.load(tmp_path, "a", devices) is None

    monkeypatch.setattr(program_store, "MAX_ENTRIES", 3)
    for i in range(5):
        (tmp_path / f"old{i}.bin").write_bytes(b"x")
        os.utime(tmp_path / f"old{i}.bin", (i, i))
    assert program_store.save(tmp_path, "new", f)
    assert sorted(p.name for p in tmp_path.glob("*.bin")) == ["a.bin", "new.bin", "old4.bin"]
    assert not list(tmp_path.glob(".*.tmp"))

    # A folder that cannot be written: no entry, no exception (the store only saves time).
    (tmp_path / "a_file").write_text("")
    assert program_store.save(tmp_path / "a_file" / "programs", "b", f) is False


def test_entry_names_follow_what_shapes_the_programs(tmp_path):
    devices = (jax.devices()[0],)
    base = program_store.store_names(easy_config(), devices)
    assert len(set(base.values())) == 3
    # Seeds, run length and cadences are arguments or runner-state fields: same programs.
    assert program_store.store_names(easy_config(train__seed=9, train__total_env_steps=24000, train__eval_every=7), devices) == base
    # The shapes change with the envs: new init and chunk, and a new evaluation only if it changes.
    other = program_store.store_names(easy_config(env__num_envs=32), devices)
    assert other["init"] != base["init"] and other["chunk"] != base["chunk"]
    # A sweep's traced programs are others; they share the plain run's evaluation.
    traced = program_store.store_names(easy_config(), devices, traced=True)
    assert traced["chunk"] != base["chunk"] and traced["evaluate"] == base["evaluate"]
    # The programs hold a tank set's solids (constants): an edited tank file is a new entry.
    tank = tmp_path / "tank.yaml"
    tank.write_text("floor_top: -1.3\n")
    in_tank = program_store.store_names(easy_config(env__scenario=0, env__tank=str(tank)), devices)
    tank.write_text("floor_top: -1.5\n")
    assert program_store.store_names(easy_config(env__scenario=0, env__tank=str(tank)), devices)["chunk"] != in_tank["chunk"]
    # An edited checkout never loads an old entry.
    program_store.source_digest.cache_clear()
    try:
        original = program_store.source_digest()
        with pytest.MonkeyPatch.context() as mp:
            mp.setattr(program_store, "source_digest", lambda: original[::-1])
            assert program_store.store_names(easy_config(), devices)["chunk"] != base["chunk"]
    finally:
        program_store.source_digest.cache_clear()
