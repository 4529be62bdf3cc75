"""The program store: a later launch loads the compiled programs an earlier one stored, without
building the env or tracing, and they compute exactly what the compiled ones do; a damaged entry is
a miss; entry names follow what shapes the programs and nothing else."""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from docrl_jax.train import program_store, programs

from _trainer_common import easy_config, result_of, wait_for


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


def test_a_tiered_start_runs_the_quick_chunk_until_the_full_one_is_ready_and_stores_only_the_full_one(
        tmp_path, monkeypatch):
    # What a cold start on a GPU does, on this CPU: the full chunk's compile is held until the quick build
    # (the actor's sequence loop rolled, `programs.quick_config`) has run a chunk, then released.
    config, devices = easy_config(), (jax.devices()[0],)
    plain, _ = programs.compile_programs(config, devices)   # memoised: the first test compiled it
    names = program_store.store_names(config, devices)
    monkeypatch.setattr(programs, "_COMPILED", {})
    monkeypatch.setattr(program_store, "folder", lambda: tmp_path)
    release, compile_full = threading.Event(), programs._compile_and_store

    def held_until_released(*args, **kwargs):   # in the full build's thread: its failure is the future's
        wait_for(release, "the test to release the full build's compile")
        return compile_full(*args, **kwargs)
    monkeypatch.setattr(programs, "_compile_and_store", held_until_released)
    before = jax.config.jax_enable_compilation_cache   # a persistent-cache hit could not be stored on a CPU
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        tiered, _ = programs.compile_programs(config, devices, tiered=True)
        assert isinstance(tiered.chunk, programs.Tiered) and not jax.config.jax_threefry_gpu_kernel_lowering
        keys, total = jnp.stack([jax.random.PRNGKey(3)]), jnp.asarray(4000, jnp.int32)
        state, _ = tiered.chunk(plain.init(keys, total))   # the quick build ran it; the full one is not stored yet
        assert tiered.chunk.quick_calls == 1 and not (tmp_path / f"{names['chunk']}.bin").exists()
        release.set()
        result_of(tiered.chunk.full, "the full build's compile")
        expected = plain.chunk(jax.tree.map(jnp.copy, state))
        taken_over = tiered.chunk(state)
    finally:
        release.set()
        jax.config.update("jax_enable_compilation_cache", before)
    assert tiered.chunk.quick_calls == 1 and tiered.chunk.full is None
    assert (tmp_path / f"{names['chunk']}.bin").exists()
    assert _leaves_equal(expected, taken_over)   # the full build is the run's own chunk


def test_tiered_waits_for_its_first_build_then_switches_to_the_full_one_and_raises_failures():
    quick_calls, full_calls, asked = [], [], threading.Event()

    class Watched(Future):   # says when a call asks for the quick build
        def result(self, timeout=None):
            asked.set()
            return super().result(timeout)

    first, full = Watched(), Future()
    chunk = programs.Tiered(first, full)
    assert chunk.compiling and chunk.ready_at is None
    caller = ThreadPoolExecutor(1)
    try:
        call = caller.submit(chunk, 1)
        wait_for(asked, "the first call to ask for the quick build")
        assert not call.done() and chunk.ready_at is None   # it waits for the build, which is not there yet
        first.set_result(lambda s: quick_calls.append(s) or s)
        assert result_of(call, "the first call") == 1 and chunk.ready_at is not None
    finally:
        first.cancel()   # nothing once the build is set; else (a failed test) ends the call's wait
        caller.shutdown()
    assert chunk(2) == 2 and chunk.quick_calls == 2 and chunk.compiling
    full.set_result(lambda s: full_calls.append(s) or -s)
    assert not chunk.compiling
    assert chunk(3) == -3 and chunk(4) == -4
    assert quick_calls == [1, 2] and full_calls == [3, 4] and chunk.quick_calls == 2

    for which in ("first", "full"):
        ok, failed = Future(), Future()
        ok.set_result(lambda s: s)
        failed.set_exception(RuntimeError("XLA failed"))
        with pytest.raises(RuntimeError, match="XLA failed"):
            (programs.Tiered(failed) if which == "first" else programs.Tiered(ok, failed))(0)


def test_a_launch_says_what_still_compiles_at_its_start_and_its_end():
    """run and sweep print these lines: while the chunk has no build the compile line says so, and at the end
    the process names the builds it waits for."""
    first, full, evaluation = Future(), Future(), Future()
    progs = programs.Programs(init=None, chunk=programs.Tiered(first, full), evaluate=programs.Tiered(evaluation),
                              state_shape=None)
    assert programs.chunk_building(progs) and "compiles on" in programs.building_note(progs)
    assert programs.still_compiling_line(progs).startswith(
        "the training program's full build and the evaluation program are still compiling")
    first.set_result(None)
    evaluation.set_result(None)
    assert programs.building_note(progs) == "" and programs.still_compiling_line(progs).startswith(
        "the training program's full build is still compiling")
    full.set_result(None)
    assert programs.still_compiling_line(progs) is None
    loaded = progs._replace(chunk=lambda *a: None, evaluate=lambda *a: None)   # a warm start's programs
    assert not programs.chunk_building(loaded) and programs.still_compiling_line(loaded) is None


def test_a_tiered_start_with_evaluation_lanes_returns_before_its_chunk_and_compiles_the_evaluation_after_it(
        tmp_path, monkeypatch):
    # The compiles are recorded, not run: what returns when, and in which order the compiles start.
    config, devices = easy_config(train__eval_alongside=True), (jax.devices()[0],)
    monkeypatch.setattr(programs, "_COMPILED", {})
    started, release_quick = [], threading.Event()

    def compile_lowered(lowered, platform, options=None):
        name = str(lowered.compiler_ir("stablehlo").operation.attributes["sym_name"]).strip('"')
        quick = options == programs.QUICK_CHUNK_OPTIONS
        started.append(f"{name} quick" if quick else name)
        compiled_with[name] = options
        if quick:
            wait_for(release_quick, "the test to release the quick chunk's compile")
        fake = lambda *args: name   # noqa: E731
        fake.out_info = lowered.out_info
        return fake, True

    compiled_with = {}
    monkeypatch.setattr(program_store, "compile_lowered", compile_lowered)
    monkeypatch.setattr(program_store, "save", lambda *a: True)
    try:
        progs, _ = programs.compile_programs(config, devices, tiered=True)
        # Returned with the quick chunk still compiling: a run initialises meanwhile.
        assert progs.chunk.compiling and progs.chunk.ready_at is None, "the quick compile's wait timed out"
        assert progs.init() == "jit_init"
        assert isinstance(progs.evaluate, programs.Tiered) and "jit_evaluate" not in started
    finally:
        release_quick.set()
    assert progs.chunk() == "jit_chunk" and progs.evaluate() == "jit_evaluate"   # each waits for its build
    assert started.index("jit_evaluate") > started.index("jit_chunk quick")
    assert sorted(started) == ["jit_chunk", "jit_chunk quick", "jit_eval_starts", "jit_evaluate", "jit_init"]
    # The evaluation, compiled beside training, without XLA's autotuner; the full chunk as a warm start runs it.
    assert compiled_with["jit_evaluate"] == {"xla_gpu_autotune_level": 0} and compiled_with["jit_chunk"] is None


def test_kernel_random_is_restored_and_leaves_a_set_value_alone():
    for user_value in (False, True):
        jax.config.update("jax_threefry_gpu_kernel_lowering", user_value)
        try:
            with programs.kernel_random(True):
                assert jax.config.jax_threefry_gpu_kernel_lowering
            with programs.kernel_random(False):
                assert jax.config.jax_threefry_gpu_kernel_lowering == user_value
            assert jax.config.jax_threefry_gpu_kernel_lowering == user_value
        finally:
            jax.config.update("jax_threefry_gpu_kernel_lowering", False)


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
    # So do runs that differ only in their learner (critics, targets, replay); not those whose actor differs.
    learner = program_store.store_names(easy_config(agent__n_step=2, agent__critic_hidden=[32, 32],
                                                    agent__critic_layer_norm=True, replay__batch_size=32), devices)
    assert learner["chunk"] != base["chunk"] and learner["evaluate"] == base["evaluate"]
    for actor in (dict(agent__actor_hidden=[16]), dict(agent__algo="sac"), dict(agent__memory=False, replay__burn_in=0)):
        assert program_store.store_names(easy_config(**actor), devices)["evaluate"] != base["evaluate"], actor
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


class _Planted:
    """A pickle that, once loaded, makes a folder: what another user could leave in a shared cache."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return os.mkdir, (self.marker,)


def test_entries_others_may_have_written_are_never_loaded(tmp_path, monkeypatch, capfd):
    """An entry is a pickle: loading it runs what it holds. One another user owns, or its group or
    anyone may write, is not opened further: one warning line, a miss (the run compiles)."""
    import pickle
    devices = (jax.devices()[0],)
    store, marker = tmp_path / "programs", tmp_path / "ran"
    store.mkdir(mode=0o700)
    (store / "planted.bin").write_bytes(pickle.dumps(_Planted(marker)))
    os.chmod(store / "planted.bin", 0o600)
    # The probe can see a load: an entry of one's own is unpickled (and then is no program: a miss).
    assert program_store.load(store, "planted", devices) is None and marker.is_dir()
    marker.rmdir()
    assert capfd.readouterr().err == ""

    def refused(mode: int, owner_offset: int = 0) -> str:
        monkeypatch.setattr(program_store, "_warned", set(), raising=False)
        monkeypatch.setattr(program_store, "_current_uid", lambda: os.getuid() + owner_offset, raising=False)
        os.chmod(store / "planted.bin", mode)
        assert program_store.load(store, "planted", devices) is None
        assert not marker.exists(), "the entry was unpickled"
        err = capfd.readouterr().err
        assert len(err.splitlines()) == 1 and str(store / "planted.bin") in err, err
        return err

    assert "writable by its group" in refused(0o620)
    assert "writable by others" in refused(0o602)
    assert "owned by another user" in refused(0o600, owner_offset=1)
    # One warning per entry, however often it is asked for.
    assert program_store.load(store, "planted", devices) is None and capfd.readouterr().err == ""


def test_a_cache_folder_others_may_write_is_not_used(tmp_path, monkeypatch, capfd):
    """Neither the cache folder (JAX's cache holds executables) nor the store folder inside it is used
    when another user owns it or others may write it: one warning line each, the run compiles.
    Folders the store makes itself only their owner may write."""
    monkeypatch.setattr(program_store, "_warned", set(), raising=False)
    saved = jax.config.jax_compilation_cache_dir
    try:
        mine = tmp_path / "mine"
        assert program_store.enable_compile_cache(str(mine)) == str(mine)
        assert program_store.folder() == mine / "programs"
        f = jax.jit(lambda x: x + 1.0).lower(jnp.ones(2)).compile()
        assert program_store.save(mine / "programs", "f", f)
        assert os.stat(mine).st_mode & 0o077 == 0 and os.stat(mine / "programs").st_mode & 0o077 == 0
        assert capfd.readouterr().err == ""

        os.chmod(mine / "programs", 0o770)               # the store folder: not read
        assert program_store.folder() is None
        err = capfd.readouterr().err
        assert len(err.splitlines()) == 1 and "programs is writable by its group" in err, err

        shared = tmp_path / "shared"
        shared.mkdir(mode=0o777)
        os.chmod(shared, 0o1777)                         # a lab's shared folder (sticky, as /tmp)
        jax.config.update("jax_compilation_cache_dir", None)
        assert program_store.enable_compile_cache(str(shared)) is None
        assert jax.config.jax_compilation_cache_dir is None and program_store.folder() is None
        err = capfd.readouterr().err
        assert len(err.splitlines()) == 1 and f"{shared} is writable by others" in err, err

        monkeypatch.setattr(program_store, "_current_uid", lambda: os.getuid() + 1, raising=False)
        assert program_store.enable_compile_cache(str(tmp_path / "theirs")) is None
        assert "owned by another user" in capfd.readouterr().err
    finally:
        jax.config.update("jax_compilation_cache_dir", saved)
