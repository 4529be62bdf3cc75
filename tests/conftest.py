"""Shared fixtures: environments and their jitted functions are built once per parameter set, since
compiling an MJX step costs seconds on CPU while running it costs milliseconds."""

from __future__ import annotations

import functools
import os
import shutil
import tempfile

# The suite mostly compiles (a run's programs take 30-50 s on 2 cores, running them seconds). XLA's
# CPU back end at optimisation level 1, not 2: measured on the procedural learning test's programs,
# compile 34 s against 51 s and its 160k training steps no slower (45 s against 52 s). Only the
# machine code changes: every comparison in the suite is between programs built under the same flags.
# Set before JAX creates its backend; a subprocess inherits it (and may append its own).
os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=1".strip()

# Tests that launch training through the command line turn on JAX's persistent compilation cache, by
# default in the user's home (~/.cache/docrl_jax/jax). The suite keeps its own instead: one folder per
# pytest run, made by the first process (xdist's workers inherit it) and removed by it at the end. No test
# writes into the home folder, and a machine that ran the suite before compiles what a clean CI machine
# compiles, so the suite's time is the same wherever it runs.
if "DOCRL_JAX_COMPILE_CACHE" not in os.environ:
    os.environ["DOCRL_JAX_COMPILE_CACHE"] = tempfile.mkdtemp(prefix="docrl_jax_test_cache_")
    os.environ["DOCRL_JAX_TEST_CACHE_OWNER"] = str(os.getpid())

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs


@functools.lru_cache(maxsize=None)
def _env_fns(scenario: int, overrides: tuple):
    env = envs.make(scenario, **dict(overrides))

    def rollout(state, actions):
        def body(s, a):
            s = env.step(s, a)
            return s, (s.obs, s.reward, s.done, s.info)
        return jax.lax.scan(body, state, actions)

    compiled = jax.jit(rollout, compiler_options=FAST_COMPILE)

    def padded_rollout(state, actions):
        """Runs len(actions) steps. Always compiles ROLLOUT_STEPS (padding with the last action) so
        every test of one parameter set shares a single compiled program."""
        n = actions.shape[0]
        assert n <= ROLLOUT_STEPS, n
        pad = jnp.broadcast_to(actions[-1], (ROLLOUT_STEPS - n, actions.shape[1]))
        final, outs = compiled(state, jnp.concatenate([actions, pad]))
        return final, jax.tree.map(lambda x: x[:n], outs)

    return env, jax.jit(env.reset_to, compiler_options=FAST_COMPILE), padded_rollout


ROLLOUT_STEPS = 80
# XLA's cheapest CPU back end (what jax_disable_most_optimizations sets): for programs that compile
# for seconds and run for milliseconds. Not bit for bit the programs of level 1 (a 60-step rollout
# differed by up to 1e-5), so every program shared between files is built under one setting:
# env_fns' always under this one, whichever file builds it first.
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
# Every test compiles under FAST_COMPILE (pytest_runtest_setup below) but those of LEVEL1_TESTS: most
# of the suite compiles programs it then runs for a few chunks or trials, and unoptimised code saves a
# third of the compile (the easy config's chunk: 10.0 -> 6.6 s alone) while running 3.4x slower (a
# 4,000-step chunk 0.66 -> 2.26 s). LEVEL1_TESTS run long (the 160k-step learning runs; the trainer
# tests that share their programs, through _trainer_common, and resume runs for many chunks; the
# structures' flyability checks): level 1 pays there. Measured over the whole suite on 2 cores,
# see LEVEL1_TESTS.


# ------------------------------------------------------------------ how two workers share the suite
# CI runs `pytest -n 2 --dist loadfile` on 2 cores, and the suite is CPU-bound: compiling dominates.
# With loadfile a work unit is a test file; here it is also one of the units below. A unit of several
# files holds tests that reuse the programs one of them compiles (memoised in the process: in one
# worker they compile once, in two twice); a single test as a unit is a long one that need not wait
# for the rest of its file. The units go out heaviest first, then every other file in collection
# order, so that short files fill in at the end and both workers finish together (xdist's own order,
# by number of tests, put the 2-test file that trains for minutes last). The order is by the CPU
# seconds each unit took in a whole run of the suite here; a renamed file or test only loses its
# place, never a test. (xdist's own grouping, --dist loadgroup with xdist_group marks, does not group
# under pytest 9.2: it sets a node id attribute that pytest no longer reads.)
EASY_TRAINER = ("tests/train/test_train.py", "tests/train/test_run_safety.py", "tests/train/test_sweep.py",
                "tests/train/test_program_store.py", "tests/train/test_best_policy.py",
                "tests/train/test_train_video.py",
                "tests/train/test_learning.py::test_td3_lstm_learns_the_easy_task")  # _trainer_common's programs
# Level 1 (JAX's default here). The whole suite on 2 cores with -n 2: 1,062 s with only six env files
# FAST; 919 s with every file FAST but test_learning.py, where the trainer unit took 103 s and the
# structures 38 s more than at level 1 (and test_train's vmapped-seeds losses left its 1e-3 tolerance);
# 900 s with these at level 1. Alone, file by file: test_eval_alongside.py (a run of 12 chunks, stopped and
# resumed) 111 -> 58 s at level 1, test_robustness.py 71 -> 53 s; no gain (or a loss) for test_env_contract,
# test_adapters, test_evaluate + test_video, test_physics, test_procedural, test_export_parity,
# test_program_constants, test_route_follower.
LEVEL1_TESTS = (*EASY_TRAINER, "tests/train/test_learning.py", "tests/envs/test_structures.py",
                "tests/train/test_eval_alongside.py", "tests/evaluate/test_robustness.py")
HEAVIEST_FIRST = (
    EASY_TRAINER,
    ("tests/train/test_learning.py",),   # its other test: the procedural tanks' programs, then 160k steps
    ("tests/train/test_sharding.py",),
    ("tests/envs/test_env_contract.py",),
    ("tests/envs/test_adapters.py", "tests/envs/test_rendering.py"),   # the Gymnasium envs' programs
    ("tests/train/test_eval_alongside.py",),
    ("tests/evaluate/test_evaluate.py", "tests/evaluate/test_video.py"),   # the evaluator's rollout
    ("tests/evaluate/test_robustness.py",),
    ("tests/export/test_export_parity.py",),
    ("tests/envs/test_physics.py",),
    ("tests/envs/test_procedural.py",),
    ("tests/envs/test_randomization.py",),
    ("tests/envs/test_structures.py",),
    ("tests/algorithms/test_learner_recipe.py",),
    ("tests/train/test_programs.py",),
    ("tests/envs/test_tanks.py",),
    ("tests/evaluate/test_tank_trials.py",),
)


def _unit(nodeid: str) -> tuple[int, str]:
    """(place in HEAVIEST_FIRST, unit name) of a test: the unit of the longest member naming it; an
    unlisted test's unit is its file, after every listed one."""
    best = (len(HEAVIEST_FIRST), nodeid.split("::")[0], 0)
    for place, members in enumerate(HEAVIEST_FIRST):
        for member in members:
            if (nodeid == member or nodeid.startswith((member + "::", member + "["))) and len(member) > best[2]:
                best = (place, members[0], len(member))
    return best[:2]


def pytest_collection_modifyitems(items):
    """Heaviest units first (stable: a unit keeps its tests' order); the workers send this order."""
    items.sort(key=lambda item: _unit(item.nodeid)[0])


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """FAST_COMPILE for every program built in a test (its module fixtures included: this runs
    before them), but in LEVEL1_TESTS; a run's programs are stored and memoised under that setting
    (program_store.JAX_FLAGS), so the two never mix."""
    jax.config.update("jax_disable_most_optimizations", not item.nodeid.startswith(LEVEL1_TESTS))


@pytest.hookimpl(optionalhook=True)   # a pytest-xdist hook
def pytest_xdist_make_scheduler(config, log):
    """--dist loadfile over the units above, handed out in collection order."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class Units(LoadFileScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return _unit(nodeid)[1]

    config.option.loadscopereorder = False
    return Units(config, log)


@pytest.fixture(scope="session")
def same_picture():
    """same_picture(a, b): asserts two renders of the same scene are the same picture. Not bit for
    bit: with another process rendering at the same time (the suite's two workers), Mesa's llvmpipe
    drew a few pixels of one of two identical renders differently (8 of 18,432 values, up to 30 levels
    apart; 1 run in 3, never alone). A different scene differs by a mean of several levels."""
    def check(a, b):
        assert a.shape == b.shape and a.dtype == b.dtype
        diff = np.abs(a.astype(int) - b.astype(int))
        assert (diff > 0).mean() <= 0.002 and diff.mean() <= 0.05, ((diff > 0).mean(), diff.mean())
    return check


@pytest.fixture(scope="session")
def env_fns():
    """env_fns(scenario, **overrides) -> (env, reset_to, rollout), jitted, cached per process.

    rollout(state, actions (T, 3)) -> (final state, (obs, reward, done, info) stacked over T <= 80)."""
    def get(scenario: int = 1, **overrides):
        return _env_fns(scenario, tuple(sorted(overrides.items())))
    return get


def pytest_unconfigure(config):
    if os.environ.get("DOCRL_JAX_TEST_CACHE_OWNER") == str(os.getpid()):
        shutil.rmtree(os.environ["DOCRL_JAX_COMPILE_CACHE"], ignore_errors=True)
