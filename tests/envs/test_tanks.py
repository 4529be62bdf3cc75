"""Tank files (docrl_jax/envs/tanks.py) against independent references: the slots a file fills, checked
against numbers computed here by hand; save and load round trips (a file, and a held-out procedural layout
with beams and tilted bars); one-line refusals of broken files; the range fan against `mujoco.mj_ray` on the
loaded tank compiled into a MuJoCo model; the hull check against a loaded box; `envs.make(tank=...)` under
jit, its starts and goals inside the file's regions.

Compiled programs: the loader's check (one per parameter set), one held-out layout, and one env (vmapped
reset and step, reset_to and step, the fan)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
import yaml

import docrl_jax.envs as envs
from docrl_jax.envs import geometry, layouts, sensors, tanks
from docrl_jax.envs.params import BOX_SLOTS

BOXES = slice(1, 1 + BOX_SLOTS)      # slot order: floor, boxes, capsules (layouts.SLOT_NAMES)
CAPSULES = slice(1 + BOX_SLOTS, None)
PARKED = np.array([0.0, 0.0, -50.0])
SHELF_TOP = 1.1                      # the shelf box's top face (centre z 1.0, half height 0.1)
# A wall across the tank (x = 0) with an opening at y in (-0.3, 1.1): air starts on one side, water on the
# other; a shelf in the air on the water's side, a pipe under water.
TANK = {
    "name": "wall_one_opening",
    "description": "A wall across the tank with one opening.",
    "floor_top": -1.3,
    "air": {"min": [-4.3, -4.3, 0.5], "max": [-1.5, 4.3, 4.0]},
    "water": {"min": [1.5, -4.3, -1.0], "max": [4.3, 4.3, -0.4]},
    "solids": [
        {"type": "box", "name": "wall_south", "center": [0.0, -2.6, 1.7], "half_extents": [0.15, 2.3, 3.0]},
        {"type": "box", "name": "wall_north", "center": [0.0, 3.0, 1.7], "half_extents": [0.15, 1.9, 3.0]},
        {"type": "box", "name": "shelf", "center": [2.6, -2.6, 1.0], "half_extents": [0.8, 0.8, 0.1],
         "yaw": 30.0},
        {"type": "capsule", "name": "pipe", "from": [1.0, 2.0, -0.8], "to": [4.0, 2.0, -0.2], "radius": 0.15},
    ],
}


def _write(folder, data, name="tank.yaml"):
    path = folder / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def params():
    return envs.make_params(0, wind=False)


@pytest.fixture(scope="module")
def tank_file(tmp_path_factory):
    return _write(tmp_path_factory.mktemp("tank"), TANK)


def _host(layout):
    return jax.tree.map(np.asarray, jax.device_get(layout))


# ---------------------------------------------------------------- loading and saving
def test_a_file_fills_the_slots_as_written(tank_file, params):
    lay = _host(tanks.load(tank_file, params))
    np.testing.assert_allclose(lay.pos[0], [0.0, 0.0, -1.4], atol=1e-6)             # floor top -1.3
    np.testing.assert_array_equal(lay.size[0], np.array([5.0, 5.0, 0.1], np.float32))
    assert lay.z_min == pytest.approx(-1.1) and lay.index == 0
    np.testing.assert_allclose(lay.regions, [[[-4.3, -4.3, 0.5], [-1.5, 4.3, 4.0]],
                                             [[1.5, -4.3, -1.0], [4.3, 4.3, -0.4]]], atol=1e-6)
    # Boxes in file order; the shelf yawed 30 degrees: its local x along (cos 30, sin 30, 0).
    np.testing.assert_allclose(lay.pos[1:4], [[0, -2.6, 1.7], [0, 3.0, 1.7], [2.6, -2.6, 1.0]], atol=1e-6)
    np.testing.assert_allclose(lay.size[3], [0.8, 0.8, 0.1], atol=1e-6)
    np.testing.assert_allclose(lay.rot[3][:, 0], [np.cos(np.pi / 6), np.sin(np.pi / 6), 0.0], atol=1e-6)
    # The pipe: centre the midpoint, local z along from -> to, size (radius, half length, 0).
    axis = np.array([3.0, 0.0, 0.6])
    np.testing.assert_allclose(lay.pos[CAPSULES][0], [2.5, 2.0, -0.5], atol=1e-6)
    np.testing.assert_allclose(lay.rot[CAPSULES][0][:, 2], axis / np.linalg.norm(axis), atol=1e-6)
    np.testing.assert_allclose(lay.size[CAPSULES][0], [0.15, np.linalg.norm(axis) / 2, 0.0], atol=1e-6)
    # Every other slot parked.
    np.testing.assert_array_equal(lay.pos[BOXES][3:], np.broadcast_to(PARKED, (BOX_SLOTS - 3, 3)))
    np.testing.assert_array_equal(lay.pos[CAPSULES][1:], np.broadcast_to(PARKED, (7, 3)))
    # The clear points: inside their regions and goal_clearance from every obstacle.
    for medium in (0, 1):
        point = lay.clear[medium]
        assert np.all(lay.regions[medium, 0] - 1e-6 <= point) and np.all(point <= lay.regions[medium, 1] + 1e-6)
        gap = geometry.signed_distance(layouts.obstacles(jax.tree.map(jnp.asarray, lay)), jnp.asarray(point))
        assert float(gap) >= params.goal_clearance


def _used(layout, kind):
    """(pos, rot, size) of the used slots of one kind (floor, boxes or capsules), in slot order."""
    lay = _host(layout)
    used = lay.pos[kind][:, 2] != -50.0
    return [x[kind][used] for x in (lay.pos, lay.rot, lay.size)]


def _same_tank(a, b):
    """Layouts equal to ~1e-5 as the file holds them: the used solids in slot order (a file lists no parked
    slot), boxes fully, capsules as their segments (a capsule's spin about its own axis changes nothing and
    is not written); the regions and the lower bound."""
    for kind in (slice(0, 1), BOXES, CAPSULES):
        (pos_a, rot_a, size_a), (pos_b, rot_b, size_b) = _used(a, kind), _used(b, kind)
        assert pos_a.shape == pos_b.shape
        np.testing.assert_allclose(pos_a, pos_b, atol=1e-5)
        np.testing.assert_allclose(size_a, size_b, atol=1e-5)
        axes = slice(None) if kind is not CAPSULES else slice(2, 3)
        np.testing.assert_allclose(rot_a[..., axes], rot_b[..., axes], atol=1e-5)
    for name in ("regions", "z_min"):
        np.testing.assert_allclose(getattr(_host(a), name), getattr(_host(b), name), atol=1e-5)


HELD_OUT = 40   # a held-out layout with a pitched beam and a tilted bar, every solid inside the tank


def test_save_and_load_give_the_layout_back(tank_file, params, tmp_path):
    loaded = tanks.load(tank_file, params)
    _same_tank(tanks.load(tanks.save(loaded, tmp_path / "again.json", params), params), loaded)
    held = jax.jit(lambda: layouts.held_out(HELD_OUT, params))()
    host = _host(held)
    used = host.pos[:, 2] != -50.0
    assert np.any(used[BOXES] & (np.abs(host.rot[BOXES][:, 2, 2]) < 0.999))     # a pitched beam
    assert np.any(used[CAPSULES] & (host.rot[CAPSULES][:, 2, 2] < 0.9))          # a tilted bar
    path = tanks.save(held, tmp_path / "held.yaml", params, description="Held-out layout 40.")
    text = yaml.safe_load(path.read_text())
    assert text["name"] == "held" and len(text["solids"]) == int(used[1:].sum())
    _same_tank(tanks.load(path, params), held)
    assert tanks.names(tmp_path) == ["again", "held"]   # sorted by file name; save's default name: the stem


# ---------------------------------------------------------------- refusals
def _solid(name, center, half=(0.3, 0.3, 0.3)):
    return {"type": "box", "name": name, "center": list(center), "half_extents": list(half)}


def _posts(n):
    return [_solid(f"post_{i}", (-4.0 + 0.5 * (i % 16), -4.5 + 3.0 * (i // 16), 0.0), (0.1, 0.1, 0.1))
            for i in range(n)]


REFUSED = {
    "start region inside a solid": (
        {**TANK, "solids": TANK["solids"] + [_solid("block_a", (-2.9, 0.0, 2.25), (1.6, 4.7, 2.0))]},
        ["the air region lies inside solid 'block_a'"]),
    "too many solids": ({**TANK, "solids": _posts(25)},
                        ["24 boxes and 8 capsules at most: solid 'post_24' is box 25"]),
    "a solid outside the tank": ({**TANK, "solids": [_solid("roof", (0.0, 0.0, 5.6))]},
                                 ["solid 'roof' lies outside the tank", "5.4"]),
    "an unknown key": ({**TANK, "solids": [{**_solid("post", (3, 3, 0)), "colour": "red"}]},
                       ["solid 'post'", "unknown key 'colour'", "center, half_extents"]),
    "a misspelt key": ({**TANK, "solids": [{**_solid("post", (3, 3, 0)), "half_extent": [0.2, 0.2, 1.0]}]},
                       ["unknown key 'half_extent'", "did you mean 'half_extents'?"]),
    "an unknown type": ({**TANK, "solids": [{"type": "cylinder", "name": "drum"}]},
                        ["solid 'drum'", "unknown type 'cylinder'", "box, capsule"]),
    "a misspelt type": ({**TANK, "solids": [{"type": "capsul", "name": "pipe"}]},
                        ["unknown type 'capsul'", "did you mean 'capsule'?"]),
    "a floor too deep": ({**TANK, "floor_top": -4.5}, ["floor_top -4.5", "-4.4 .. -0.8"]),
    "a water region in the air": ({**TANK, "water": [3.0, 3.0, 0.5]}, ["the water region", "z < 0"]),
    "no way through": (
        {**TANK, "solids": [_solid("wall_full", (0.0, 0.0, 2.0), (0.15, 5.0, 3.4))]},
        ["no route from the air region to the water region: solid 'wall_full' closes every way",
         "a gap must be >= ~1.1 m wide"]),
    # The wall's opening 0.9 m wide (y 0 .. 0.9): its best cells, y = 0.5, keep 0.4 m from wall_b.
    "an opening too narrow": (
        {**TANK, "solids": [_solid("wall_a", (0.0, -2.5, 2.0), (0.15, 2.5, 3.4)),
                            _solid("wall_b", (0.0, 2.95, 2.0), (0.15, 2.05, 3.4))]},
        ["no route from the air region to the water region", "the widest way keeps at most 0.40 m from the solids",
         "beside solid 'wall_b' and solid 'wall_a'", "a gap must be >= ~1.1 m wide"]),
    # A goal 0.3 m above the floor and goal_clearance (1.0 m) under a slab: a free cell keeps 0.55 m from both,
    # and the band that does, z -1.24 .. -1.04, holds no cell centre: no free cell within the arrival distance.
    "a goal under a slab near the floor": (
        {**TANK, "floor_top": -1.79, "water": [2.0, 0.0, -1.49],
         "solids": [_solid("slab", (2.0, 0.0, -0.39), (1.5, 1.5, 0.1))]},
        ["the water region at [2.0, 0.0, -1.49] lies 0.30 m above the floor and 1.00 m from solid 'slab': "
         "no free cell within the arrival distance 0.5 m of it"]),
}


@pytest.mark.parametrize("case", REFUSED)
def test_broken_files_are_refused_in_one_line(case, params, tmp_path):
    data, expected = REFUSED[case]
    path = _write(tmp_path, data)
    with pytest.raises(tanks.TankError) as error:
        tanks.load(path, params)
    message = str(error.value)
    assert "\n" not in message and message.startswith(str(path.resolve())), message
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize("water", [[2.0, 0.0, -1.0], {"min": [1.0, -1.0, -1.1], "max": [3.0, 1.0, -0.9]}],
                         ids=["a point", "a layer"])
def test_goals_near_the_floor_load(water, params, tmp_path):
    """Water 0.2-0.4 m above the floor (the paper puts its underwater goals 0.3 m above it), below every free
    cell (0.55 m up): the trips end within the arrival distance of it, so an empty tank of it loads."""
    layout = _host(tanks.load(_write(tmp_path, {"floor_top": -1.3, "air": [-2.0, 0.0, 2.0], "water": water}),
                              params))
    np.testing.assert_allclose(layout.clear, [[-2.0, 0.0, 2.0], [2.0, 0.0, -1.0]], atol=1e-6)


def test_sets_resolve_folders_and_names(tmp_path, params):
    with pytest.raises(tanks.TankError, match="holds no tank file"):
        tanks.load_set(tmp_path, params)
    with pytest.raises(tanks.TankError, match="nor a packaged tank; packaged: "):
        tanks.load_set("no_such_tank", params)
    with pytest.raises(tanks.TankError, match=r"did you mean 'wall_opening_air'\?$"):
        tanks.load_set("wall_openning_air", params)


# ---------------------------------------------------------------- the env in a tank
STATES = 12


@pytest.fixture(scope="module")
def tank_env(tank_file, params):
    """(env, the loaded layout, one program: vmapped reset + step of STATES keys, and reset_to + step of
    given poses; the fan, jitted and vmapped)."""
    env = envs.make(tank=tank_file, wind=False)
    layout = tanks.load(tank_file, params)
    hover = jnp.array([-1.0, 0.0, 0.0])

    @jax.jit
    def play(keys, positions, goal):
        reset = jax.vmap(env.reset)(keys)
        placed = jax.vmap(lambda k, x: env.reset_to(k, x, 0.0, goal, layout=layout))(keys[:len(positions)], positions)
        both = jax.tree.map(lambda a, b: jnp.concatenate([a, b]), reset, placed)
        stepped = jax.vmap(lambda s: env.step(s, hover))(both)      # one batch: one compiled step
        return reset, jax.tree.map(lambda x: x[:STATES], stepped), jax.tree.map(lambda x: x[STATES:], stepped)

    # The hull's sphere cover 3 cm into the shelf's top, and 5 cm above it.
    positions = jnp.array([[2.6, -2.6, SHELF_TOP + geometry.HULL_SPHERE_RADIUS + gap] for gap in (-0.03, 0.05)])
    out = jax.device_get(play(jax.random.split(jax.random.PRNGKey(3), STATES), positions, jnp.array([-3.0, 3.0, 3.0])))
    return env, layout, out, jax.jit(jax.vmap(env._cast, (0, None, 0, 0, 0)))


def test_make_tank_resets_and_steps_in_the_files_regions(tank_env):
    env, layout, (reset, stepped, _), _ = tank_env
    assert env.tanks.index.shape == (1,)
    regions = np.asarray(layout.regions)
    for state in (reset, stepped):
        assert np.all(np.isfinite(state.obs)) and not np.any(state.info["collision"])
    np.testing.assert_allclose(reset.sim.layout.pos, np.broadcast_to(layout.pos, reset.sim.layout.pos.shape))
    media = set()
    for point in np.concatenate([reset.info["position"], reset.sim.goal]):
        medium = int(point[2] < 0)
        media.add(medium)
        assert np.all(regions[medium, 0] - 1e-5 <= point) and np.all(point <= regions[medium, 1] + 1e-5), point
    assert media == {0, 1}


def _rays_against_mj_ray(cast, data, layout, qpos) -> tuple[float, int]:
    """(largest |range - mj_ray's| over the fan of every pose in `qpos` (N, 7) in `layout`, beams that hit
    one of the layout's box slots): `cast` is the env's vmapped `_cast`, `data` an env state's MJX data."""
    model = layouts.mj_model(jax.device_get(layout))
    mj_data = mujoco.MjData(model)
    body = model.body("huauv").id
    rots = []
    for q in qpos:
        mj_data.qpos[:7] = q[:7]
        mujoco.mj_forward(model, mj_data)
        rots.append(mj_data.xmat[body].reshape(3, 3).copy())
    underwater = qpos[:, 2] < 0.0
    batch = jax.tree.map(lambda x: jnp.broadcast_to(x[0] if x.ndim and x.shape[0] == len(qpos) else x,
                                                    (len(qpos),) + (x.shape[1:] if x.ndim and x.shape[0] == len(qpos)
                                                                    else x.shape)), data)
    ours = np.asarray(cast(batch, layout, jnp.asarray(qpos[:, :3]), jnp.asarray(np.stack(rots)), jnp.asarray(underwater)))
    worst, hits = 0.0, 0
    for i, q in enumerate(qpos):
        mj_data.qpos[:7] = q[:7]
        mujoco.mj_forward(model, mj_data)
        fov, max_range = (90.0, 20.0) if underwater[i] else (270.0, 10.0)
        for j, a in enumerate(sensors.beam_angles(fov)):
            geom = np.zeros(1, np.int32)
            dist = mujoco.mj_ray(model, mj_data, q[:3], rots[i] @ np.array([np.cos(a), np.sin(a), 0.0]),
                                 np.array(sensors.RAY_GEOMGROUP, np.uint8), 1, body, geom)
            worst = max(worst, abs(ours[i, j] - (max_range if dist < 0 else min(dist, max_range))))
            hits += dist >= 0 and model.geom(int(geom[0])).name.startswith("slot_")
    return worst, hits


def test_rays_match_mj_ray_on_a_loaded_tank(tank_env):
    env, layout, (reset, _, _), cast = tank_env
    worst, hits = _rays_against_mj_ray(cast, reset.sim.data, layout, np.asarray(reset.sim.data.qpos))
    assert worst < 1e-3, worst
    assert hits > 40   # the beams meet the file's boxes, not only the tank's walls


@pytest.mark.parametrize("name", ["ceiling_one_hole", "pipe_grid", "room_door_water"])
def test_rays_match_mj_ray_in_gallery_tanks(tank_env, params, name):
    env, _, (reset, _, _), cast = tank_env
    layout = tanks.load(tanks.packaged_dir() / f"{name}.yaml", params)
    rng = np.random.default_rng(0)
    regions = np.asarray(layout.regions)
    points = np.concatenate([rng.uniform(regions[m, 0], regions[m, 1], (6, 3)) for m in (0, 1)])
    # Random yaw and a pitch of up to 35 degrees, so the fans sweep the ceilings and pipes above and below.
    quats = []
    for yaw, pitch in zip(rng.uniform(-np.pi, np.pi, len(points)), rng.uniform(-0.6, 0.6, len(points))):
        q = np.zeros(4)
        mujoco.mju_mulQuat(q, np.array([np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]),
                           np.array([np.cos(pitch / 2), 0, np.sin(pitch / 2), 0]))
        quats.append(q)
    worst, hits = _rays_against_mj_ray(cast, reset.sim.data, layout, np.concatenate([points, quats], -1))
    assert worst < 1e-3, worst
    assert hits > 10   # the gallery tank's own solids are seen (boxes and the pipes' capsules)


def test_hull_touching_a_loaded_box_collides(tank_env):
    env, _, (_, _, placed), _ = tank_env
    info = placed.info
    assert np.all(info["ranges"].min(-1) > env.params.collision_distance)   # the fan (level) misses the shelf
    assert info["collision"].tolist() == [True, False], info["collision"]
    assert placed.done.tolist() == [True, False]
