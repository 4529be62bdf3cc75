"""Structured tanks (docrl_jax/envs/structures.py, structure_families.py) against independent references:
shapes against `layouts.generate`'s, the structure's solids and the regions read from the raw slot arrays
and checked with numpy distances of our own, the id split on many draws, flyability (`flyability.check`)
and a dividing wall's sides found from its boxes.

Compiled programs: the held-out layouts of N ids (structures._programs, which `held_out_set` shares), their
flyability check, and the small id-only draws (everything but the index is dead code there)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import docrl_jax.envs as envs
from docrl_jax.envs import layouts, structures
from docrl_jax.envs.params import BOX_SLOTS, RANDOM_BOXES, RANDOM_CAPSULES

N = 64
STRUCT_BOXES = slice(1 + RANDOM_BOXES, 1 + BOX_SLOTS)            # slots 12..23 of the boxes
STRUCT_CAPS = slice(1 + BOX_SLOTS + RANDOM_CAPSULES, None)        # slots 6..7 of the capsules
OBSTACLES = slice(1, None)
PARKED_Z = -50.0
WALL, REACH, TOP = 4.9, 5.1, 5.4    # inner wall faces; solids may reach the walls' outer faces; walls' top


@pytest.fixture(scope="module")
def built():
    p = envs.make_params(0)
    make, check, families = structures._programs(p)
    lay = jax.device_get(make(jnp.arange(N)))
    return p, make, check, lay, np.asarray(families(jnp.arange(N)))


def _one(tree, i):
    return jax.tree.map(lambda x: np.asarray(x)[i], tree)


def _distances(lay, point):
    """Distance from `point` to every used obstacle slot of one layout: boxes by projection onto each box in
    its frame, capsules by the nearest of 2,001 points along the segment, minus the radius."""
    pos, rot, size = (np.asarray(x, np.float64) for x in (lay.pos, lay.rot, lay.size))
    out = []
    for s in range(1, pos.shape[0]):
        if pos[s, 2] == PARKED_Z:
            continue
        if s <= BOX_SLOTS:
            local = rot[s].T @ (point - pos[s])
            out.append(np.linalg.norm(local - np.clip(local, -size[s], size[s])))
        else:
            seg = pos[s] + np.linspace(-1, 1, 2001)[:, None] * rot[s][:, 2] * size[s, 1]
            out.append(np.linalg.norm(seg - point, axis=-1).min() - size[s, 0])
    return np.array(out)


def test_shapes_dtypes_and_parking_match_the_random_generator(built):
    p, _, _, lay, _ = built
    ref = jax.eval_shape(lambda k: layouts.generate(k, p), jax.random.PRNGKey(0))
    for name in ("pos", "rot", "size", "z_min", "clear", "index", "regions"):
        got = getattr(lay, name)
        assert got.shape == (N,) + getattr(ref, name).shape and got.dtype == getattr(ref, name).dtype, name
    assert np.all(np.isfinite(lay.pos)) and np.all(np.isfinite(lay.rot)) and np.all(np.isfinite(lay.size))
    eye = np.einsum("nsji,nsjk->nsik", lay.rot, lay.rot)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-5)
    np.testing.assert_array_equal(lay.index, structures.index_of(np.arange(N)))
    # Every structure slot is used or parked at exactly (0, 0, -50); every layout uses some.
    used = lay.pos[:, 1:, 2] != PARKED_Z
    np.testing.assert_array_equal(lay.pos[:, 1:][~used], np.broadcast_to([0.0, 0.0, PARKED_Z], (np.sum(~used), 3)))
    struct_used = np.concatenate([lay.pos[:, STRUCT_BOXES, 2], lay.pos[:, STRUCT_CAPS, 2]], 1) != PARKED_Z
    assert np.all(struct_used.any(1))


def test_every_family_is_drawn_and_every_structure_solid_lies_inside_the_tank(built):
    p, _, _, lay, fam = built
    assert set(fam.tolist()) == set(range(len(structures.FAMILIES))), np.bincount(fam)
    floor_top = lay.pos[:, 0, 2] + lay.size[:, 0, 2]
    for i in range(N):
        boxes = lay.pos[i, STRUCT_BOXES, 2] != PARKED_Z
        # Structure boxes are axis-aligned: corners are centre -+ half extents.
        np.testing.assert_array_equal(lay.rot[i, STRUCT_BOXES][boxes], np.broadcast_to(np.eye(3), (boxes.sum(), 3, 3)))
        lo = lay.pos[i, STRUCT_BOXES][boxes] - lay.size[i, STRUCT_BOXES][boxes]
        hi = lay.pos[i, STRUCT_BOXES][boxes] + lay.size[i, STRUCT_BOXES][boxes]
        caps = lay.pos[i, STRUCT_CAPS, 2] != PARKED_Z
        axis = lay.rot[i, STRUCT_CAPS][caps][:, :, 2] * lay.size[i, STRUCT_CAPS][caps][:, 1:2]
        radius = lay.size[i, STRUCT_CAPS][caps][:, :1]
        ends = np.concatenate([lay.pos[i, STRUCT_CAPS][caps] + axis, lay.pos[i, STRUCT_CAPS][caps] - axis])
        lo = np.concatenate([lo, ends - np.concatenate([radius, radius])])
        hi = np.concatenate([hi, ends + np.concatenate([radius, radius])])
        assert np.all(np.abs(lo[:, :2]) <= REACH + 1e-5) and np.all(np.abs(hi[:, :2]) <= REACH + 1e-5), i
        assert np.all(hi[:, 2] <= TOP + 1e-5) and np.all(lo[:, 2] >= floor_top[i] - 0.2 - 1e-5), i
        assert np.all(hi - lo > 0.05), i


def test_regions_lie_in_their_medium_and_the_clear_points_are_free(built):
    p, _, _, lay, _ = built
    half = WALL - p.wall_margin
    floor_top = lay.pos[:, 0, 2] + lay.size[:, 0, 2]
    for i in range(N):
        (air_lo, air_hi), (water_lo, water_hi) = lay.regions[i]
        assert np.all(air_lo <= air_hi + 1e-6) and np.all(water_lo <= water_hi + 1e-6), (i, lay.regions[i])
        for lo, hi in lay.regions[i]:
            assert np.all(np.abs(lo[:2]) <= half + 1e-5) and np.all(np.abs(hi[:2]) <= half + 1e-5), i
        assert p.air_z_range[0] - 1e-6 <= air_lo[2] and air_hi[2] <= p.air_z_range[1] + 1e-6, i
        band_lo, band_hi = p.water_band(float(lay.z_min[i]))
        assert water_lo[2] >= max(band_lo, floor_top[i] + 0.1) - 1e-5 and water_hi[2] <= band_hi + 1e-6, i
        # The clear points (the env's fallback start and goal) lie in their regions, goal_clearance from
        # every obstacle, random or built.
        one = _one(lay, i)
        for medium in (0, 1):
            point = one.clear[medium].astype(np.float64)
            assert np.all(point >= lay.regions[i, medium, 0] - 1e-5) and np.all(point <= lay.regions[i, medium, 1] + 1e-5)
            assert _distances(one, point).min() >= p.goal_clearance - 1e-4, (i, medium)


def test_same_id_same_layout_whatever_the_batch(built):
    _, make, _, lay, _ = built
    ids = np.array([5, 63, 0, 17] * (N // 4))   # the same compiled program, the ids at other batch positions
    again = jax.device_get(make(jnp.asarray(ids)))
    for name in ("pos", "rot", "size", "z_min", "clear", "regions", "index"):
        np.testing.assert_array_equal(getattr(again, name)[:4], getattr(lay, name)[ids[:4]], err_msg=name)
    assert len({lay.pos[i].tobytes() for i in range(N)}) == N


def test_training_and_held_out_ids_never_meet_and_the_mix_follows_layout_structures():
    keys = jax.random.split(jax.random.PRNGKey(3), 20_000)
    index = lambda q: np.asarray(jax.jit(jax.vmap(lambda k: structures.draw(k, q).index))(keys))  # noqa: E731
    mixed = index(envs.make_params(0, layout_structures=0.5))
    held = index(envs.make_params(0, layout_structures=1.0, layout_held_out=True))
    structured = np.asarray(structures.is_structured(mixed))
    assert 0.48 < structured.mean() < 0.52
    train_ids = np.asarray(structures.structured_id(mixed[structured]))
    assert train_ids.min() >= structures.HELD_OUT_IDS and train_ids.max() <= 2**31 - 2
    assert len(np.unique(train_ids)) > 0.99 * len(train_ids)
    # A plain layout's index is its id (>= 0; training ids here), never a structured one's.
    assert np.all(mixed[~structured] >= layouts.HELD_OUT_IDS)
    assert np.all(structures.is_structured(held))
    held_ids = np.asarray(structures.structured_id(held))
    assert held_ids.min() >= 0 and held_ids.max() < structures.HELD_OUT_IDS and len(np.unique(held_ids)) > 8_000
    assert not np.any(structures.is_structured(np.array([-1, 0, 2**31 - 2])))
    np.testing.assert_array_equal(structures.structured_id(structures.index_of(np.array([0, 7, 2**31 - 3]))),
                                  [0, 7, 2**31 - 3])


def _dividing_plane(lay, i):
    """(axis, low face, high face) of a wall across the tank built from one layout's structure boxes: all
    of them share one thin extent on a horizontal axis and together span the tank on the other."""
    used = lay.pos[i, STRUCT_BOXES, 2] != PARKED_Z
    lo = (lay.pos[i, STRUCT_BOXES] - lay.size[i, STRUCT_BOXES])[used]
    hi = (lay.pos[i, STRUCT_BOXES] + lay.size[i, STRUCT_BOXES])[used]
    for axis in (0, 1):
        if np.ptp(lo[:, axis]) < 1e-5 and np.ptp(hi[:, axis]) < 1e-5 and hi[0, axis] - lo[0, axis] <= 0.4 + 1e-5:
            other = 1 - axis
            if lo[:, other].min() <= -WALL and hi[:, other].max() >= WALL:
                return axis, lo[0, axis], hi[0, axis]
    return None


def test_a_dividing_walls_regions_lie_on_opposite_sides(built):
    p, _, _, lay, fam = built
    walls = [i for i in np.nonzero(fam == structures.FAMILIES.index("wall"))[0] if _dividing_plane(lay, i)]
    assert len(walls) >= 5, walls
    for i in walls:
        axis, face_lo, face_hi = _dividing_plane(lay, i)
        (air_lo, air_hi), (water_lo, water_hi) = lay.regions[i]
        low_side = air_hi[axis] <= face_lo - p.goal_clearance + 1e-5 and water_lo[axis] >= face_hi + p.goal_clearance - 1e-5
        high_side = water_hi[axis] <= face_lo - p.goal_clearance + 1e-5 and air_lo[axis] >= face_hi + p.goal_clearance - 1e-5
        assert low_side or high_side, (i, axis, face_lo, face_hi, lay.regions[i])


def test_most_ids_are_flyable_both_ways_and_the_held_out_set_takes_the_first_flyable(built):
    p, _, _, lay, fam = built
    # held_out_set checks ids 64 at a time (the fixture's compiled programs): 58 flyable ones found among
    # ids 0..63 means at least 90.6 % of those 64 are flyable both ways.
    held = structures.held_out_set(58, p)
    assert held.ids.max() < N, held.ids
    assert np.all(np.diff(held.ids) > 0) and held.ids.min() >= 0
    np.testing.assert_array_equal(held.layouts.index, structures.index_of(held.ids))
    np.testing.assert_array_equal(held.layouts.pos, lay.pos[held.ids])
    np.testing.assert_array_equal(held.family, fam[held.ids])
    assert np.all(np.isfinite(held.length)) and np.all(held.length >= held.straight * 0.99)
    # The structures make trips longer than the straight line (walls, ceilings, dead ends: a detour).
    ratio = held.length / held.straight
    assert np.median(ratio) > 1.1, np.median(ratio)
    detours = {structures.FAMILIES[f]: np.median(ratio[held.family == f]) for f in set(held.family.tolist())}
    assert detours["ceiling"] > 1.3 and detours["wall"] > 1.1, detours
    with pytest.raises(structures.StructuresError, match="held-out set holds 1 .. 10000"):
        structures.held_out_set(0, p)
