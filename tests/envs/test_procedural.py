"""Procedural tanks (scenario 0, docrl_jax/envs/layouts.py) against independent references: the
layout rules checked on hundreds of vmapped layouts with numpy distances of our own (projection onto
each box, dense sampling of each capsule's segment, read from the raw slot poses), reproducibility
and the held-out split of the ids, starts and goals of `reset`, the range fan against `mujoco.mj_ray`
on the layout compiled into a MuJoCo model, the hull check against a generated riser, and rendering.

Compiled programs: one vmapped layout batch, the id draws, one vmapped reset batch, the fan, and the
`conftest.env_fns(0, wind=False)` reset and rollout (shared by the collision and rendering tests)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax.envs import geometry, layouts, sensors
from docrl_jax.envs.params import BOX_SLOTS, CAPSULE_SLOTS

PROCEDURAL = dict(wind=False)       # the scenario-0 parameter set of this module (one compile each)
HOVER = jnp.array([-1.0, 0.0, 0.0])
BOXES = slice(1, 1 + BOX_SLOTS)     # slot order: floor, boxes, capsules (layouts.SLOT_NAMES)
CAPSULES = slice(1 + BOX_SLOTS, None)
PARKED = np.array([0.0, 0.0, -50.0])
WALL = 4.9                          # inner wall faces at x, y = +-4.9 (assets/common.xml)
HULL_BACK = 0.157 + 0.12            # body -x extent of the hull's sphere cover (geometry.HULL_SPHERE_*)


# ---------------------------------------------------------------- numpy references
def _box_distance(points, pos, rot, half):
    """Unsigned distance (P, B) from points (P, 3) to boxes, by projecting onto each box in its frame
    (0 inside)."""
    local = np.einsum("bji,pbj->pbi", rot, points[:, None] - pos[None])
    closest = np.clip(local, -half[None], half[None])
    return np.linalg.norm(local - closest, axis=-1)


def _capsule_distance(points, pos, rot, size, samples=4001):
    """Distance (P, C) from points to capsules: the nearest of `samples` points along each segment,
    minus the radius (an overestimate by at most ~(spacing / 2)^2 / (2 d), i.e. < 1e-5 m here)."""
    axis = rot[:, :, 2] * size[:, 1:2]
    t = np.linspace(-1.0, 1.0, samples)
    seg = pos[:, None] + t[None, :, None] * axis[:, None]                     # (C, S, 3)
    d = np.linalg.norm(points[:, None, None] - seg[None], axis=-1).min(-1)   # (P, C)
    return d - size[None, :, 0]


def _obstacle_distances(layout, points):
    """(box distances (P, 12), capsule distances (P, 6)) of one layout's slots, from its raw arrays."""
    pos, rot, size = (np.asarray(x, np.float64) for x in (layout.pos, layout.rot, layout.size))
    points = np.atleast_2d(np.asarray(points, np.float64))
    return (_box_distance(points, pos[BOXES], rot[BOXES], size[BOXES]),
            _capsule_distance(points, pos[CAPSULES], rot[CAPSULES], size[CAPSULES]))


def _tank_distance(layout, points, skip_capsule=None):
    """Distance from points to every solid of the episode's tank (walls, floor, used obstacles), leaving
    out capsule slot `skip_capsule`."""
    points = np.atleast_2d(np.asarray(points, np.float64))
    boxes, caps = _obstacle_distances(layout, points)
    if skip_capsule is not None:
        caps = np.delete(caps, skip_capsule, axis=1)
    floor_top = float(layout.pos[0, 2] + layout.size[0, 2])
    walls = WALL - np.abs(points[:, :2]).max(-1)
    return np.minimum.reduce([boxes.min(-1), caps.min(-1), points[:, 2] - floor_top, walls])


def _one(tree, i):
    return jax.tree.map(lambda x: np.asarray(x)[i], tree)


# ---------------------------------------------------------------- layouts
N_HELD = 32   # held-out layouts generated alongside (the riser search, the rays, reproducibility)


@pytest.fixture(scope="module")
def generated():
    """One compiled program: layouts(keys, ids) -> (256 layouts as episodes draw them, the same ids
    generated with their clear points moved far away (nothing removed for clearance: the drawn counts),
    layouts.held_out(ids) for N_HELD ids)."""
    p = envs.make_params(0, **PROCEDURAL)
    far = jnp.full((2, 3), 100.0)

    @jax.jit
    def run(keys, ids):
        drawn = jax.vmap(lambda k: layouts.draw(k, p))(keys)
        free = jax.vmap(lambda i: layouts.generate(layouts.layout_key(i), p, clear=far))(drawn.index)
        return drawn, free, jax.vmap(lambda i: layouts.held_out(i, p))(ids)

    keys = jax.random.split(jax.random.PRNGKey(7), 256)
    return p, lambda ids=jnp.arange(N_HELD): jax.device_get(run(keys, jnp.asarray(ids, jnp.int32)))


@pytest.fixture(scope="module")
def drawn(generated):
    p, run = generated
    lay, free, _ = run()
    return p, lay, free


@pytest.fixture(scope="module")
def held(generated):
    """Held-out layouts 0 .. N_HELD - 1 (host arrays)."""
    return generated[1]()[2]


def test_layouts_keep_the_documented_shape(drawn):
    p, lay, free = drawn
    n = lay.pos.shape[0]
    # The floor: a 10 x 10 m slab whose top lies in layout_floor_top; the episode's bound 0.2 m above.
    floor_top = lay.pos[:, 0, 2] + lay.size[:, 0, 2]
    assert np.all(lay.pos[:, 0, :2] == 0) and np.all(lay.size[:, 0] == np.array([5.0, 5.0, 0.1], np.float32))
    assert np.all((floor_top >= p.layout_floor_top[0] - 1e-6) & (floor_top <= p.layout_floor_top[1] + 1e-6))
    np.testing.assert_allclose(lay.z_min, floor_top + 0.2, atol=1e-6)
    assert floor_top.min() < -1.9 and floor_top.max() > -1.4     # the whole range is used
    # A slot is used or parked at exactly (0, 0, -50).
    used = lay.pos[:, 1:, 2] != -50.0
    np.testing.assert_array_equal(lay.pos[:, 1:][~used], np.broadcast_to(PARKED, lay.pos[:, 1:][~used].shape))
    free_used = free.pos[:, 1:, 2] != -50.0
    for name, sl, slots, (lo, hi) in (("box", slice(0, BOX_SLOTS), BOX_SLOTS, p.layout_boxes),
                                      ("capsule", slice(BOX_SLOTS, None), CAPSULE_SLOTS, p.layout_capsules)):
        # Without removals the used slots are the first k, k uniform in the range (both ends seen).
        k = free_used[:, sl].sum(-1)
        assert np.all((k >= lo) & (k <= hi)), (name, k.min(), k.max())
        assert k.min() == lo and k.max() == hi, (name, k.min(), k.max())
        np.testing.assert_array_equal(free_used[:, sl], np.arange(slots)[None] < k[:, None])
        # A drawn layout uses a subset of those: the same slots unless removed for clearance.
        assert np.all(used[:, sl] <= free_used[:, sl])
        assert np.all(used[:, sl].sum(-1) <= hi)
    # Used centres inside the tank, |x|, |y| <= 4.3; obstacle poses and sizes are the same with and
    # without removals (removal parks a slot, it does not redraw the others).
    centres = lay.pos[:, 1:][used]
    assert np.all(np.abs(centres[:, :2]) <= 4.3 + 1e-6)
    np.testing.assert_array_equal(lay.pos[:, 1:][used], free.pos[:, 1:][used])
    np.testing.assert_array_equal(lay.size, free.size)
    np.testing.assert_array_equal(lay.rot, free.rot)
    # Sizes in their documented ranges; rotations orthonormal.
    assert np.all((lay.size[:, BOXES, 1] >= 0.1) & (lay.size[:, BOXES, 1] <= 0.3))       # half thickness
    assert np.all((lay.size[:, CAPSULES, 0] >= 0.1) & (lay.size[:, CAPSULES, 0] <= 0.6))  # radius
    eye = np.einsum("nsji,nsjk->nsik", lay.rot, lay.rot)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-5)
    # Each used obstacle stands on the floor (a riser: vertical capsule whose segment starts 0.05 m inside
    # the floor; a post or panel: upright box from 0.1 m inside it) or is a beam / bar hanging at least
    # 0.3 m above the episode's lower bound (a box pitched at most 0.4 rad, a capsule tilted 45-90 deg).
    beams = 0
    for i in range(n):
        top = floor_top[i]
        for s in range(1, 1 + BOX_SLOTS + CAPSULE_SLOTS):
            if not used[i, s - 1]:
                continue
            pos, rot, size = lay.pos[i, s], lay.rot[i, s], lay.size[i, s]
            capsule = s > BOX_SLOTS
            bottom = pos[2] - size[1] if capsule else pos[2] - size[2]
            standing = rot[2, 2] > 1 - 1e-6 and abs(bottom - (top - (0.05 if capsule else 0.1))) < 1e-5
            tilt = np.arccos(np.clip(rot[2, 2], -1, 1))
            hanging = (lay.z_min[i] + 0.3 - 1e-5 <= pos[2] <= 4.4 + 1e-5
                       and ((np.pi / 4 - 1e-4 <= tilt <= np.pi / 2 + 1e-4) if capsule else tilt <= 0.4 + 1e-4))
            assert standing or hanging, (i, s, pos, size, tilt)
            beams += int(hanging and not standing)
    assert 0.25 < beams / used.sum() < 0.45, beams / used.sum()   # layout_beam_fraction 0.35


def test_clear_points_are_clear_and_removals_are_justified(drawn):
    p, lay, free = drawn
    clearance = p.goal_clearance
    removed_any = 0
    for i in range(lay.pos.shape[0]):
        one, one_free = _one(lay, i), _one(free, i)
        clear = one.clear
        # The air point in air, the water point in the water band over this layout's floor.
        assert np.all(np.abs(clear[:, :2]) <= WALL - p.wall_margin + 1e-6)
        assert p.air_z_range[0] <= clear[0, 2] <= p.air_z_range[1]
        assert one.z_min + 0.1 - 1e-5 <= clear[1, 2] <= -0.3 + 1e-6
        # Every obstacle the layout keeps is at least goal_clearance from both points (numpy reference
        # and the library's signed distance agree) ...
        boxes, caps = _obstacle_distances(one, clear)
        used = one.pos[1:, 2] != -50.0
        kept = np.concatenate([boxes, caps], 1)[:, used]
        assert kept.size == 0 or kept.min() >= clearance - 1e-4, (i, kept.min())
        lib = float(geometry.signed_distance(layouts.obstacles(one), jnp.asarray(clear[0])))
        lib = min(lib, float(geometry.signed_distance(layouts.obstacles(one), jnp.asarray(clear[1]))))
        if kept.size:
            assert lib == pytest.approx(kept.min(), abs=1e-4)
        # ... and every slot it dropped had been nearer than that to one of them.
        boxes, caps = _obstacle_distances(one_free, clear)
        near = np.concatenate([boxes, caps], 1).min(0) < clearance
        dropped = (one_free.pos[1:, 2] != -50.0) & ~used
        np.testing.assert_array_equal(dropped, (one_free.pos[1:, 2] != -50.0) & near)
        removed_any += int(dropped.any())
    assert 10 < removed_any < lay.pos.shape[0]   # the rule is exercised, not degenerate


def test_held_out_ids_are_never_drawn_in_training(drawn, held):
    p, lay, _ = drawn
    assert np.all(lay.index >= layouts.HELD_OUT_IDS)
    np.testing.assert_array_equal(held.index, np.arange(N_HELD))
    assert len({tuple(held.pos[i].ravel()) for i in range(N_HELD)}) == N_HELD   # distinct layouts
    # Many draws: training ids never fall in the held-out range; with layout_held_out they always do.
    keys = jax.random.split(jax.random.PRNGKey(3), 20_000)
    ids = lambda q: np.asarray(jax.jit(jax.vmap(lambda k: layouts.draw(k, q).index))(keys))  # noqa: E731
    train, held_ids = ids(p), ids(envs.make_params(0, layout_held_out=True, **PROCEDURAL))
    assert train.min() >= layouts.HELD_OUT_IDS and train.max() < 2**31 - 1 and len(np.unique(train)) > 19_900
    assert held_ids.min() >= 0 and held_ids.max() < layouts.HELD_OUT_IDS and len(np.unique(held_ids)) > 8_000


# ---------------------------------------------------------------- resets
@pytest.fixture(scope="module")
def proc(env_fns):
    return env_fns(0, **PROCEDURAL)


def test_reset_starts_and_goals_are_clear_and_inside_the_episodes_bounds(proc, generated):
    env, _, _ = proc
    p = env.params
    states = jax.device_get(jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(11), N_HELD)))
    # Same id, same layout: each episode's layout is generate(layout_key(its id)), here regenerated by
    # another program.
    again = generated[1](states.sim.layout.index)[2]
    for name in ("pos", "rot", "size", "z_min"):
        np.testing.assert_allclose(getattr(again, name), getattr(states.sim.layout, name), atol=1e-6, err_msg=name)
    assert np.all(states.sim.layout.index >= layouts.HELD_OUT_IDS)
    wet = 0
    for i in range(N_HELD):
        layout = _one(states.sim.layout, i)
        start, goal = states.info["position"][i], states.info["goal"][i]
        used = layout.pos[1:, 2] != -50.0
        for point in (start, goal):
            boxes, caps = _obstacle_distances(layout, point)
            gaps = np.concatenate([boxes, caps], 1)[:, used]
            assert gaps.size == 0 or gaps.min() >= p.goal_clearance - 1e-4, (i, point, gaps.min())
            assert np.all(np.abs(point[:2]) <= WALL - p.wall_margin + 1e-6)
            if point[2] < 0:   # water: above this layout's own floor bound, below -0.3
                assert layout.z_min + 0.1 - 1e-5 <= point[2] <= -0.3 + 1e-6, (i, point, layout.z_min)
                wet += 1
            else:
                assert p.air_z_range[0] <= point[2] <= p.air_z_range[1]
        assert np.linalg.norm(goal - start) >= p.min_goal_distance - 1e-5
    assert 12 < wet < 52
    assert not np.any(states.done) and not np.any(states.info["collision"])


@pytest.mark.parametrize("fixed", [{"z_bounds": (-1.9, 4.8)}, {"water_z_range": (-1.7, -0.3)}])
def test_underwater_starts_stay_above_each_layouts_floor_whatever_the_fixed_bands(fixed):
    # A fixed lower bound or water band may reach below a procedural floor (which lies anywhere in
    # layout_floor_top): the sampler keeps starts and goals at least 0.1 m above the episode's floor.
    env = envs.make(0, wind=False, start_water_fraction=1.0, goal_water_fraction=1.0, **fixed)
    s = jax.jit(jax.vmap(env.reset))(jax.random.split(jax.random.PRNGKey(0), 64))
    top = np.asarray(jax.vmap(layouts.floor_top)(s.sim.layout))
    assert np.all(np.asarray(s.info["position"][:, 2]) >= top + 0.1 - 1e-5)
    assert np.all(np.asarray(s.sim.goal[:, 2]) >= top + 0.1 - 1e-5)


# ---------------------------------------------------------------- rays
@pytest.fixture(scope="module")
def cast(proc):
    env, _, _ = proc
    return jax.jit(env._cast)


@pytest.mark.parametrize("index", [0, 1, 2])
def test_rays_match_mj_ray_on_generated_layouts(proc, cast, held, index):
    env, _, _ = proc
    host = _one(held, index)
    layout = jax.tree.map(jnp.asarray, host)
    m = layouts.mj_model(host)
    d = mujoco.MjData(m)
    body = m.body("huauv").id
    assert body == env.body_id
    rng = np.random.default_rng(index)
    worst, counts, hits = 0.0, {True: 0, False: 0}, 0
    while min(counts.values()) < 8:
        underwater = counts[True] < counts[False]
        z = rng.uniform(float(host.z_min) + 0.05, -0.05) if underwater else rng.uniform(0.05, 4.6)
        pos = np.array([rng.uniform(-4.6, 4.6), rng.uniform(-4.6, 4.6), z])
        if _tank_distance(host, pos)[0] < 0.1:   # start outside every solid
            continue
        counts[underwater] += 1
        quat = rng.normal(size=4)
        quat[1:3] *= 0.3   # tilted up to ~35 degrees
        quat /= np.linalg.norm(quat)
        d.qpos[:3], d.qpos[3:7] = pos, quat
        mujoco.mj_forward(m, d)
        rot = d.xmat[body].reshape(3, 3)
        ours = np.asarray(cast(env._data0, layout,
                               jnp.asarray(pos, jnp.float32), jnp.asarray(rot, jnp.float32), jnp.asarray(underwater)))
        fov, max_range = (90.0, 20.0) if underwater else (270.0, 10.0)
        ref = []
        for a in sensors.beam_angles(fov):
            vec = rot @ np.array([np.cos(a), np.sin(a), 0.0])
            geomid = np.zeros(1, np.int32)
            dist = mujoco.mj_ray(m, d, pos, vec, np.array(sensors.RAY_GEOMGROUP, np.uint8), 1, body, geomid)
            ref.append(max_range if dist < 0 else min(dist, max_range))
            hits += int(m.geom(int(geomid[0])).name.startswith("slot_")) if dist >= 0 else 0
        worst = max(worst, float(np.max(np.abs(ours - np.array(ref)))))
    assert worst < 1e-3, worst
    assert hits > 20   # the beams do meet the layout's obstacles, not only walls and floor


# ---------------------------------------------------------------- hull collisions
def _riser_spot(batch, medium):
    """(layout, capsule slot, vehicle yaw, centres touching / clear) for a generated riser: the
    vehicle faces away from it (the riser sits in the LIDAR's rear gap; the sonar looks forward), at
    hull gaps of -0.03 m and +0.05 m, with every other solid more than 0.7 m from both centres."""
    for i in range(N_HELD):
        layout = _one(batch, i)
        z = 2.0 if medium == "air" else 0.5 * (float(layout.z_min) - 0.3)
        for s in range(CAPSULE_SLOTS):
            slot = 1 + BOX_SLOTS + s
            pos, rot, (r, half, _) = layout.pos[slot], layout.rot[slot], layout.size[slot]
            if pos[2] == -50.0 or rot[2, 2] < 1 - 1e-6 or not pos[2] - half + 0.3 < z < pos[2] + half - 0.3:
                continue
            for angle in np.linspace(-np.pi, np.pi, 24, endpoint=False):
                u = np.array([np.cos(angle), np.sin(angle), 0.0])
                centres = [np.array([pos[0], pos[1], z]) + (r + HULL_BACK + gap) * u for gap in (-0.03, 0.05)]
                if _tank_distance(layout, np.stack(centres), skip_capsule=s).min() > 0.7:
                    return layout, s, float(angle), centres
    raise AssertionError(f"no riser spot in held-out layouts 0..{N_HELD - 1} ({medium})")


@pytest.mark.parametrize("medium", ["air", "water"])
def test_hull_touching_a_generated_riser_collides_and_just_clear_does_not(proc, held, medium):
    env, reset_to, rollout = proc
    host, slot, yaw, (touching, clear) = _riser_spot(held, medium)
    layout = jax.tree.map(jnp.asarray, host)
    rot = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    goal = jnp.array([0.0, 0.0, 3.0 if medium == "water" else -0.6])   # far: no arrival
    outcome = {}
    for name, centre, gap in (("touching", touching, -0.03), ("clear", clear, 0.05)):
        # The set-up: the hull's sphere cover (geometry.HULL_SPHERE_*) is `gap` from the riser.
        spheres = centre + geometry.HULL_SPHERE_CENTRES @ rot.T
        assert _tank_distance(host, spheres).min() - geometry.HULL_SPHERE_RADIUS == pytest.approx(gap, abs=1e-3)
        s0 = reset_to(jax.random.PRNGKey(0), jnp.asarray(centre, jnp.float32), yaw, goal, layout=layout)
        _, (_, rew, done, info) = rollout(s0, HOVER[None])
        info = jax.tree.map(lambda x: np.asarray(x)[0], info)
        assert np.linalg.norm(info["position"] - centre) < 0.01         # hovered in place
        assert info["ranges"].min() > env.params.collision_distance     # the beams alone see nothing
        assert bool(info["underwater"]) == (medium == "water")
        outcome[name] = (bool(info["collision"]), bool(info["terminated"]), bool(done[0]), float(rew[0]),
                         bool(info["out_of_bounds"]))
    assert outcome["touching"] == (True, True, True, env.params.reward_collide, False), outcome
    assert outcome["clear"] == (False, False, False, 0.0, False), outcome


# ---------------------------------------------------------------- rendering
def test_render_draws_each_states_layout(proc, held, same_picture):
    from docrl_jax.envs.rendering import RenderError
    env, reset_to, rollout = proc
    key, start, goal = jax.random.PRNGKey(0), jnp.array([0.0, -4.0, 3.5]), jnp.array([0.0, 4.0, 3.5])
    states = [reset_to(key, start, np.pi / 2, goal, layout=_one(held, i)) for i in (3, 4)]
    moved, _ = rollout(states[0], jnp.tile(jnp.array([1.0, 0.0, 0.0]), (3, 1)))
    try:
        frames = env.render([states[0], moved], camera="overview", width=96, height=64, overlay=False)
        other = env.render([states[1]], camera="overview", width=96, height=64, overlay=False)
    except RenderError as error:
        pytest.skip(f"no OpenGL renderer: {error}")
    assert frames.shape == (2, 64, 96, 3) and frames.dtype == np.uint8 and frames.std() > 10
    # Same vehicle pose and goal, different tank: the obstacles change the picture.
    assert np.abs(frames[0].astype(int) - other[0].astype(int)).mean() > 2
    # The picture is the layout's: rendering with the layout compiled into a MuJoCo model by hand.
    from docrl_jax.envs.rendering import Renderer, track_from_states
    track = track_from_states([states[1]])
    with Renderer(layouts.mj_model(jax.device_get(states[1].sim.layout)), env.params, 96, 64, "overview",
                  fan=True, overlay=False) as r:
        same_picture(r.render_track(track, last=False), other)
