"""The BBA baseline: pure and jit/vmap-safe, its state machine's rules, and arrival in the empty tank."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax import evaluate
from docrl_jax.baselines.bba import CONTOUR, DEPTH, GO_FORWARD, GO_TO_TARGET, HOLD, BBAParams, make_bba

MAX_STEPS = 200


def _info(position=(0.0, 0.0, 2.5), goal=(3.0, 0.0, 2.5), yaw=0.0, ranges=None, underwater=False):
    return {"position": jnp.asarray(position, jnp.float32), "goal": jnp.asarray(goal, jnp.float32),
            "yaw": jnp.asarray(yaw, jnp.float32), "underwater": jnp.asarray(underwater),
            "ranges": jnp.full(20, 10.0) if ranges is None else jnp.asarray(ranges, jnp.float32)}


def _act(policy, carry, **kw):
    return jax.jit(policy.act)(policy.params, carry, jnp.zeros(26), _info(**kw), jax.random.PRNGKey(0))


@pytest.fixture(scope="module")
def bba():
    return make_bba()


def test_forward_when_aligned_rotate_when_not(bba):
    carry, a = _act(bba, bba.init_carry())
    assert int(carry["mode"]) == GO_FORWARD
    np.testing.assert_allclose(a, [1.0, 0.0, 0.0])            # v = 0.25, vz = 0, dpsi = 0
    _, a = _act(bba, bba.init_carry(), goal=(0.0, 3.0, 2.5))  # target to the left: turn left in place
    np.testing.assert_allclose(a, [-1.0, 0.0, 1.0])
    _, a = _act(bba, bba.init_carry(), goal=(0.0, -3.0, 2.5), yaw=0.05)
    np.testing.assert_allclose(a, [-1.0, 0.0, -1.0])


def test_heading_error_is_wrapped(bba):
    # yaw 3.1, target bearing -3.1: 0.08 rad apart the short way round, so no turn is needed.
    _, a = _act(bba, bba.init_carry(), goal=(-3.0, -0.125, 2.5), yaw=3.1)
    np.testing.assert_allclose(a, [1.0, 0.0, 0.0], atol=1e-6)


def test_blocked_then_contour_rules(bba):
    ranges = np.full(20, 10.0)
    ranges[10] = 0.8                                     # nearest straight ahead (+7 deg): blocked
    carry, a = _act(bba, bba.init_carry(), ranges=ranges)
    assert int(carry["mode"]) == CONTOUR
    np.testing.assert_allclose(a, [-1.0, 0.0, 1.0])      # "otherwise": (0, +0.25), turn left in place
    ranges = np.full(20, 10.0)
    ranges[9:11] = 2.0                                   # something ahead, nearer than the target (3 m)
    ranges[5] = 0.8                                      # nearest at -64 deg (right front): (0.15, +0.25)
    carry, a = _act(bba, carry, ranges=ranges)
    assert int(carry["mode"]) == CONTOUR
    np.testing.assert_allclose(a, [0.2, 0.0, 1.0], atol=1e-6)
    ranges[5], ranges[2] = 10.0, 0.8                     # nearest at -107 deg (right rear): (0.15, -0.25)
    carry, a = _act(bba, carry, ranges=ranges)
    assert int(carry["mode"]) == CONTOUR
    np.testing.assert_allclose(a, [0.2, 0.0, -1.0], atol=1e-6)
    # Cone of +-45 deg towards the target clear beyond the target distance: leave the contour.
    ranges[9:11] = 3.5
    carry, _ = _act(bba, carry, ranges=ranges)
    assert int(carry["mode"]) == GO_TO_TARGET


def test_depth_after_horizontal_then_hold(bba):
    carry, a = _act(bba, bba.init_carry(), goal=(0.3, 0.0, -1.0))   # xy reached: DEPTH, descend
    assert int(carry["mode"]) == DEPTH
    np.testing.assert_allclose(a, [-1.0, -1.0, 0.0])
    carry, a = _act(bba, carry, goal=(0.3, 0.0, 2.45))
    assert int(carry["mode"]) == HOLD
    np.testing.assert_allclose(a, [-1.0, 0.0, 0.0])
    carry, _ = _act(bba, carry, goal=(1.3, 0.0, 2.45))               # drifted in x-y: horizontal again
    assert int(carry["mode"]) == GO_FORWARD


def test_depth_first_and_in_air_orders():
    first = make_bba(depth_phase="first")
    carry, a = _act(first, first.init_carry(), goal=(3.0, 0.0, -1.0))
    assert int(carry["mode"]) == DEPTH and float(a[1]) == -1.0
    in_air = make_bba(depth_phase="in_air")
    carry, a = _act(in_air, in_air.init_carry(), goal=(3.0, 0.0, -1.0))   # target below: horizontal first
    assert int(carry["mode"]) == GO_FORWARD
    carry, a = _act(in_air, in_air.init_carry(), position=(3.0, 0.0, -1.0), goal=(0.0, 0.0, 2.5),
                    underwater=True)                                      # target above: climb first
    assert int(carry["mode"]) == DEPTH and float(a[1]) == 1.0
    with pytest.raises(ValueError, match="valid choices"):
        BBAParams(depth_phase="sideways")


def test_vmaps_over_trials(bba):
    n = 5
    carry = jax.vmap(lambda _: bba.init_carry())(jnp.arange(n))
    info = jax.vmap(lambda x: _info(goal=(3.0, x, 2.5)))(jnp.linspace(-3, 3, n))
    act = jax.jit(jax.vmap(bba.act, in_axes=(None, 0, None, 0, None)))
    carry, a = act(bba.params, carry, jnp.zeros(26), info, jax.random.PRNGKey(0))
    assert a.shape == (n, 3) and bool(jnp.all(jnp.abs(a) <= 1.0))


@pytest.mark.parametrize("direction", ["air_to_water", "water_to_air"])
def test_bba_reaches_goal_in_empty_tank(direction, request):
    env = request.getfixturevalue("empty_tank")
    bba = request.getfixturevalue("bba_env")
    start, goal = envs.eval_pair(1, direction)
    t = evaluate.run_trials(env, bba, start, goal, jax.random.PRNGKey(3), 4, MAX_STEPS,
                            yaw=evaluate.NOMINAL_YAW[direction])
    assert t["success"].all(), evaluate.summarize(t)
    np.testing.assert_allclose(t["t_air"] + t["t_water"], t["time"], atol=1e-6)
    assert (t["t_air"] > 0).all() and (t["t_water"] > 0).all()


@pytest.fixture(scope="module")
def empty_tank():
    return evaluate.make_eval_env(1, MAX_STEPS, z_bounds=(-3.0, 4.8))  # the env of test_evaluate.py (cached)


@pytest.fixture(scope="module")
def bba_env(empty_tank):
    return make_bba(empty_tank.params)


def test_contour_does_not_leave_while_target_is_outside_the_fan(bba):
    ranges = np.full(20, 10.0)
    ranges[10] = 0.8
    carry, _ = _act(bba, bba.init_carry(), ranges=ranges)                # blocked ahead: CONTOUR
    assert int(carry["mode"]) == CONTOUR
    # Target behind-right at -160 deg: the fan's beams near -135 deg are clear, but the target is out of view.
    behind = (3.0 * np.cos(np.deg2rad(-160)), 3.0 * np.sin(np.deg2rad(-160)), 2.5)
    carry, _ = _act(bba, carry, ranges=np.full(20, 10.0), goal=behind)
    assert int(carry["mode"]) == CONTOUR
    # Underwater the sonar fan is +-45 deg: a target at -60 deg is outside it.
    side = (3.0 * np.cos(np.deg2rad(-60)), 3.0 * np.sin(np.deg2rad(-60)), -0.5)
    carry, _ = _act(bba, carry, ranges=np.full(20, 20.0), goal=side, position=(0.0, 0.0, -0.5), underwater=True)
    assert int(carry["mode"]) == CONTOUR
    ahead = (3.0 * np.cos(np.deg2rad(-30)), 3.0 * np.sin(np.deg2rad(-30)), -0.5)
    carry, _ = _act(bba, carry, ranges=np.full(20, 20.0), goal=ahead, position=(0.0, 0.0, -0.5), underwater=True)
    assert int(carry["mode"]) == GO_TO_TARGET
