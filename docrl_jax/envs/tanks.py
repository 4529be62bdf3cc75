"""Tank files: a tank a person builds, written as YAML (or JSON), loaded into a procedural `layouts.Layout`.

    floor_top: -1.3
    air: {min: [-4.3, -4.3, 0.5], max: [-1.5, 4.3, 4.0]}      # or a point: air: [x, y, z]
    water: {min: [1.5, -4.3, -1.0], max: [4.3, 4.3, -0.4]}
    solids:
      - {type: box, name: wall, center: [0, -2.6, 1.7], half_extents: [0.15, 2.3, 3.0], yaw: 0}
      - {type: capsule, name: pipe, from: [-3, 0, -0.8], to: [3, 0, -0.8], radius: 0.2}

docs/TANKS.md lists every key and rule. `load` checks a file against those rules and raises `TankError`
(one line: the file, the solid or region, the problem, what is valid) before the env compiles anything: the
longest check, `flyability.check` (a route both ways between the air and water regions), compiles once
per parameter set (seconds on a CPU; then ~0.2 s a tank); why a tank cannot be flown is worded by
docrl_jax/envs/tank_reasons.py (its first refused route compiles `flyability.blockage`, ~3 s). `load_set`
stacks a set of tanks (a file, a folder, a packaged tank's name, or "gallery") for `HUAUVEnv`; `save`
writes any layout (e.g. `layouts.held_out(i, p)`) as a tank file to edit and fly again.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

from docrl_jax.envs import geometry, layouts, tank_reasons
from docrl_jax.envs.params import BOX_SLOTS, CAPSULE_SLOTS, EnvParams
from docrl_jax.resources import resource_dir
from docrl_jax.schema import did_you_mean

TOP_KEYS = ("name", "description", "floor_top", "air", "water", "solids")
BOX_KEYS = ("type", "name", "center", "half_extents", "yaw", "pitch", "roll")
CAPSULE_KEYS = ("type", "name", "from", "to", "radius")
REGION_KEYS = ("min", "max")
SUFFIXES = (".yaml", ".yml", ".json")
FLOOR_TOP_RANGE = (-4.4, -0.8)   # m: room under the water for a water region, above the walls' bottom (-4.6)
TOP = 5.4                        # m: the walls' top
FLOOR_DEPTH = 0.2                # m: a solid's centre may lie in the floor slab (floor_top - 0.2 .. floor_top)
_TOL = 1e-4                      # m: slack on every limit, so that a saved layout loads again
_GRID_POINTS = 33                # a side of the grid of points tried for a region's free point
_REGION_NAMES = ("air", "water")
_PACKAGED = "gallery"


class TankError(ValueError):
    """A tank file or tank set that breaks the format (docs/TANKS.md)."""


def packaged_dir() -> Path:
    """The packaged tanks (assets/tanks, the gallery)."""
    return resource_dir("assets") / "tanks"


def packaged_names() -> list[str]:
    folder = packaged_dir()
    return sorted(f.stem for f in folder.iterdir() if f.suffix in SUFFIXES) if folder.is_dir() else []


# ---------------------------------------------------------------- reading a file
def read(path: Path) -> dict:
    """The mapping a tank file holds, unchecked; `TankError` for a file that is not YAML or JSON text
    holding a mapping."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as error:
        raise TankError(f"{path}: cannot read the tank file ({error.strerror or error})") from None
    except UnicodeDecodeError:   # an image, an archive, ...
        raise TankError(f"{path}: not a text file; a tank file is YAML or JSON text (docs/TANKS.md)") from None
    try:
        data = json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (yaml.YAMLError, json.JSONDecodeError) as error:
        mark = getattr(error, "problem_mark", None)
        line = error.lineno if isinstance(error, json.JSONDecodeError) else mark.line + 1 if mark else "?"
        problem = error.msg if isinstance(error, json.JSONDecodeError) else getattr(error, "problem", None) or error
        raise TankError(f"{path}: not valid {'JSON' if path.suffix == '.json' else 'YAML'} at line {line}: "
                        f"{str(problem).splitlines()[0]}") from None
    if not isinstance(data, dict):
        raise TankError(f"{path}: a tank file holds a mapping of keys ({', '.join(TOP_KEYS)}), "
                        f"not {type(data).__name__}")
    return data


def _keys(data: dict, valid, required, where: str) -> None:
    unknown = [k for k in data if k not in valid]
    if unknown:
        raise TankError(f"{where}: unknown key {unknown[0]!r}; valid keys: {', '.join(valid)}"
                        f"{did_you_mean(str(unknown[0]), valid)}")
    missing = [k for k in required if k not in data]
    if missing:
        raise TankError(f"{where}: missing key {missing[0]!r}; required: {', '.join(required)}")


def _number(value, where: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TankError(f"{where}: {what} must be a finite number, not {value!r}")
    return float(value)


def _vector(value, where: str, what: str) -> np.ndarray:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise TankError(f"{where}: {what} must be a list of 3 numbers [x, y, z], not {value!r}")
    return np.array([_number(v, where, what) for v in value])


def _text(value, where: str, what: str) -> str:
    if not isinstance(value, str):
        raise TankError(f"{where}: {what} must be a string, not {value!r}")
    return value


def _solid(entry, i: int, where: str):
    """(kind, name, pos, rot, size) of solids[i]."""
    if not isinstance(entry, dict):
        raise TankError(f"{where}: solid {i + 1} must be a mapping with a type (box or capsule), not {entry!r}")
    kind = entry.get("type")
    if "type" not in entry:
        label = repr(entry["name"]) if isinstance(entry.get("name"), str) else str(i + 1)
        raise TankError(f"{where}: solid {label}: missing key 'type'; valid types: box, capsule")
    if kind not in ("box", "capsule"):
        label = repr(entry["name"]) if isinstance(entry.get("name"), str) else str(i + 1)
        raise TankError(f"{where}: solid {label}: unknown type {kind!r}; valid types: box, capsule"
                        f"{did_you_mean(str(kind), ('box', 'capsule'))}")
    name = _text(entry.get("name", f"{kind}_{i + 1}"), where, f"solid {i + 1}'s name")
    at = f"{where}: solid {name!r}"
    if kind == "box":
        _keys(entry, BOX_KEYS, ("type", "center", "half_extents"), at)
        pos, half = _vector(entry["center"], at, "center"), _vector(entry["half_extents"], at, "half_extents")
        if np.any(half <= 0):
            raise TankError(f"{at}: half_extents {half.tolist()} must all be > 0 (m)")
        angles = [_number(entry.get(k, 0.0), at, k) for k in ("yaw", "pitch", "roll")]
        rot = Rotation.from_euler("ZYX", angles, degrees=True).as_matrix()
        return kind, name, pos, rot, half
    _keys(entry, CAPSULE_KEYS, ("type", "from", "to", "radius"), at)
    a, b = _vector(entry["from"], at, "from"), _vector(entry["to"], at, "to")
    radius = _number(entry["radius"], at, "radius")
    if radius <= 0:
        raise TankError(f"{at}: radius {radius} must be > 0 (m)")
    half_length = np.linalg.norm(b - a) / 2
    if half_length <= 0:
        raise TankError(f"{at}: from and to are the same point; a capsule needs two different ends")
    size = np.array([radius, half_length, 0.0])
    return kind, name, (a + b) / 2, np.asarray(layouts.capsule_frame(jnp.asarray(b - a, jnp.float32))), size


def _check_inside(name, centre, floor_top: float, where: str) -> None:
    """A solid belongs to the tank when its centre lies inside it; its ends may reach into or past the
    walls, the floor and the top (the procedural generator's beams, risers and posts do), where no start,
    goal or beam can meet them."""
    beyond = float(np.abs(centre[:2]).max())
    if beyond > geometry.TANK_HALF_WIDTH + _TOL or not floor_top - FLOOR_DEPTH - _TOL <= centre[2] <= TOP + _TOL:
        raise TankError(
            f"{where}: solid {name!r} lies outside the tank (its centre {np.round(centre, 2).tolist()}); valid "
            f"centres: |x|, |y| <= {geometry.TANK_HALF_WIDTH} (the walls' inner faces), z from "
            f"{floor_top - FLOOR_DEPTH:.2f} (the floor's bottom) to {TOP} (the walls' top)")


def _region(value, medium: str, floor_top: float, p: EnvParams, where: str) -> np.ndarray:
    """(2, 3) low and high corners of the air or water region."""
    at = f"{where}: the {medium} region"
    if isinstance(value, dict):
        _keys(value, REGION_KEYS, REGION_KEYS, at)
        lo, hi = _vector(value["min"], at, "min"), _vector(value["max"], at, "max")
    elif isinstance(value, (list, tuple)):
        lo = hi = _vector(value, at, "a point")
    else:
        raise TankError(f"{at} must be {{min: [x, y, z], max: [x, y, z]}} or a point [x, y, z], not {value!r}")
    if np.any(lo > hi):
        raise TankError(f"{at}: min {lo.tolist()} lies above max {hi.tolist()} on some axis; min <= max")
    half = geometry.TANK_HALF_WIDTH - p.wall_margin
    if max(np.abs(lo[:2]).max(), np.abs(hi[:2]).max()) > half + _TOL:
        raise TankError(f"{at} reaches outside the tank's interior (x, y {lo[:2].tolist()} .. {hi[:2].tolist()}); "
                        f"valid: |x|, |y| <= {half:.2f} (the walls at 4.9 less wall_margin {p.wall_margin})")
    if medium == "air" and (lo[2] <= 0 or hi[2] > p.bounds[1] + _TOL):
        raise TankError(f"{at}: z {lo[2]} .. {hi[2]} is not all in air; valid: 0 < z <= {p.bounds[1]} "
                        "(above the water surface, up to the episode's top bound)")
    z_low = max(floor_top + 0.1, floor_top + 0.2 if p.z_bounds is None else p.bounds[0])
    if medium == "water" and (lo[2] < z_low - _TOL or hi[2] >= 0):
        raise TankError(f"{at}: z {lo[2]} .. {hi[2]} is not all in the water above the floor; valid: "
                        f"{z_low:.2f} <= z < 0 (the episode's lower bound over floor_top {floor_top}, "
                        "to the surface)")
    return np.stack([lo, hi])


def _analyse(layout: layouts.Layout, p: EnvParams):
    """One compiled program per parameter set: (flyability.check's Route; a grid of points over each
    region (2, N, 3) and their gaps to the obstacles (2, N))."""
    from docrl_jax.envs import flyability
    t = jnp.linspace(0.0, 1.0, _GRID_POINTS)

    def grid(region):
        axes = [region[0, k] + t * (region[1, k] - region[0, k]) for k in range(3)]
        return jnp.stack(jnp.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)

    solids = layouts.obstacles(layout)
    points = jax.vmap(grid)(layout.regions)
    gaps = jax.vmap(jax.vmap(lambda c: geometry.signed_distance(solids, c)))(points)
    return flyability.check(layout, p), points, gaps


_ANALYSE: dict = {}


def _free_point(layout, points, gaps, names, p: EnvParams, medium: str, where: str) -> np.ndarray:
    """A point of a region the env's sampler accepts (>= goal_clearance from every obstacle): of a grid of
    33 points a side over the region, the free one nearest its centre; else `TankError` naming the solid
    nearest the centre."""
    ok = gaps >= p.goal_clearance
    if ok.any():
        centre = points.mean(0)
        return points[ok][np.argmin(np.linalg.norm(points[ok] - centre, axis=-1))]
    gap, solid = next(x for x in tank_reasons.by_distance(layout, names, points.mean(0)) if x[1].startswith("solid"))
    if gap < 0:
        why = f"the {medium} region lies inside {solid}"
    else:
        why = (f"every point of the {medium} region lies within goal_clearance {p.goal_clearance} m of a solid "
               f"(nearest its centre: {solid})")
    raise TankError(f"{where}: {why}; a start or goal needs a point >= {p.goal_clearance} m from every solid "
                    "(move or widen the region, or move the solid)")


def _stack(*trees):
    return jax.tree.map(lambda *x: jnp.stack(x), *trees)


def _parse(path: Path, p: EnvParams) -> layouts.Layout:
    where = str(path)
    data = read(path)
    _keys(data, TOP_KEYS, ("floor_top",), where)
    for key in ("name", "description"):
        if key in data:
            _text(data[key], where, key)
    floor_top = _number(data["floor_top"], where, "floor_top")
    if not FLOOR_TOP_RANGE[0] <= floor_top <= FLOOR_TOP_RANGE[1]:
        raise TankError(f"{where}: floor_top {floor_top} m is outside the tank; valid: "
                        f"{FLOOR_TOP_RANGE[0]} .. {FLOOR_TOP_RANGE[1]} m")
    entries = data.get("solids") or []
    if not isinstance(entries, list):
        raise TankError(f"{where}: solids must be a list of boxes and capsules, not {entries!r}")
    solids = {"box": [], "capsule": []}
    for i, entry in enumerate(entries):
        kind, name, *geo = _solid(entry, i, where)
        if any(name == other[0] for group in solids.values() for other in group):
            raise TankError(f"{where}: solid {name!r} is named twice; every solid's name must be unique")
        solids[kind].append((name, *geo))
        limit = {"box": BOX_SLOTS, "capsule": CAPSULE_SLOTS}[kind]
        if len(solids[kind]) > limit:
            raise TankError(f"{where}: too many solids: {BOX_SLOTS} boxes and {CAPSULE_SLOTS} capsules at most: "
                            f"solid {name!r} is {kind} {len(solids[kind])}")
        _check_inside(name, geo[0], floor_top, where)

    def slots(kind, n):
        group = solids[kind]
        arrays = [np.array([g[k] for g in group]).reshape((-1,) + s) for k, s in ((1, (3,)), (2, (3, 3)), (3, (3,)))]
        return layouts.park_rest(*(jnp.asarray(a, jnp.float32) for a in arrays), n)

    (bp, br, bs), (cp, cr, cs) = slots("box", BOX_SLOTS), slots("capsule", CAPSULE_SLOTS)
    floor = jnp.array([[0.0, 0.0, floor_top - 0.1]]), jnp.eye(3)[None], jnp.array([[5.0, 5.0, 0.1]])
    defaults = np.asarray(layouts.default_regions(p, floor_top), np.float64)
    regions = np.stack([_region(data[m], m, floor_top, p, where) if m in data else defaults[i]
                        for i, m in enumerate(_REGION_NAMES)])
    layout = layouts.Layout(
        pos=jnp.concatenate([floor[0], bp, cp]).astype(jnp.float32),
        rot=jnp.concatenate([floor[1], br, cr]).astype(jnp.float32),
        size=jnp.concatenate([floor[2], bs, cs]).astype(jnp.float32),
        z_min=jnp.asarray(floor_top + 0.2, jnp.float32), clear=jnp.zeros((2, 3), jnp.float32),
        index=jnp.asarray(0, jnp.int32), regions=jnp.asarray(regions, jnp.float32))
    names = ([g[0] for g in solids["box"]] + [None] * (BOX_SLOTS - len(solids["box"]))
             + [g[0] for g in solids["capsule"]] + [None] * (CAPSULE_SLOTS - len(solids["capsule"])))
    if p not in _ANALYSE:
        _ANALYSE[p] = jax.jit(lambda lay: _analyse(lay, p))
    route, points, gaps = jax.device_get(_ANALYSE[p](layout))
    clear = [_free_point(layout, points[i], gaps[i], names, p, m, where) for i, m in enumerate(_REGION_NAMES)]
    layout = layout.replace(clear=jnp.asarray(np.stack(clear), jnp.float32))
    why = tank_reasons.route_refusal(layout, route, names, p)
    if why:
        raise TankError(f"{where}: {why}")
    return layout


# ---------------------------------------------------------------- loading files and sets
_CACHE: dict = {}


def _load_cached(path: Path, p: EnvParams) -> layouts.Layout:
    p = dataclasses.replace(p, tank=None)            # the env's params name the tank set: one check for all
    key = (str(path), path.stat().st_mtime_ns, p)   # an edited file loads again
    if key not in _CACHE:
        _CACHE[key] = _parse(path, p)
    return _CACHE[key]


def load(path, p: EnvParams) -> layouts.Layout:
    """The tank in one YAML/JSON file as a Layout (index 0); `TankError` if it breaks a rule."""
    path = Path(path).expanduser().resolve()
    if not path.is_file():
        raise TankError(f"{path}: no such tank file")
    return _load_cached(path, p)


def files(spec) -> list[Path]:
    """The tank files of a set: a file, a folder (its *.yaml, *.yml, *.json, sorted by name), a packaged
    tank's bare name, or "gallery" (every packaged tank)."""
    path = Path(str(spec)).expanduser()
    if not path.exists() and str(spec) == _PACKAGED:
        path = packaged_dir()
    elif not path.exists() and path.name == str(spec) and not path.suffix:
        path = packaged_dir() / f"{spec}.yaml"
        if not path.is_file():
            packaged = ", ".join(packaged_names()) or "none"
            raise TankError(f"{str(spec)!r}: no such file or folder, nor a packaged tank; packaged: {packaged} "
                            f"(or {_PACKAGED!r}, all of them){did_you_mean(str(spec), [*packaged_names(), _PACKAGED])}")
    if path.is_dir():
        found = sorted((f for f in path.iterdir() if f.suffix in SUFFIXES and f.is_file()), key=lambda f: f.name)
        if not found:
            raise TankError(f"{path}: the folder holds no tank file ({', '.join('*' + s for s in SUFFIXES)})")
        return [f.resolve() for f in found]
    if not path.is_file():
        raise TankError(f"{path}: no such tank file or folder")
    return [path.resolve()]


def load_set(spec, p: EnvParams) -> layouts.Layout:
    """The tanks of `spec` (`files`) stacked into one Layout (leading axis: the tank; `index` its position)."""
    found = files(spec)
    key = (tuple((str(f), f.stat().st_mtime_ns) for f in found), dataclasses.replace(p, tank=None))
    if key not in _CACHE:
        tanks = [_load_cached(f, p).replace(index=jnp.asarray(i, jnp.int32)) for i, f in enumerate(found)]
        _CACHE[key] = _stack(*tanks)
    return _CACHE[key]


def names(spec) -> list[str]:
    """The names of the tanks of `spec`, in set order (a file's `name`, else its stem)."""
    out = []
    for f in files(spec):
        name = read(f).get("name", f.stem)
        out.append(name if isinstance(name, str) else f.stem)
    return out


# ---------------------------------------------------------------- saving
def _round(values) -> list[float]:
    return [round(float(v), 6) + 0.0 for v in np.ravel(values)]


def save(layout: layouts.Layout, path, p: EnvParams, name: str | None = None,
         description: str | None = None) -> Path:
    """Writes one (unbatched) layout as a tank file (YAML; JSON when `path` ends in .json): its floor,
    regions and used slots (parked ones skipped), boxes with yaw, pitch and roll recovered from `rot`.
    `load` of the file gives the layout back (capsules as their segment: the spin about their own axis
    is not kept). Returns the path."""
    path = Path(path).expanduser()
    host = jax.device_get(layout)
    pos, rot, size = (np.asarray(x, np.float64) for x in (host.pos, host.rot, host.size))
    if pos.ndim != 2:
        raise TankError(f"{path}: save writes one tank; this layout holds {pos.shape[0]} (index one first)")
    data: dict = {"name": name or path.stem}
    if description is not None:
        data["description"] = description
    data["floor_top"] = round(float(pos[0, 2] + size[0, 2]), 6)
    regions = np.asarray(host.regions, np.float64)
    for i, medium in enumerate(_REGION_NAMES):
        data[medium] = {"min": _round(regions[i, 0]), "max": _round(regions[i, 1])}
    solids, counts = [], {"box": 0, "capsule": 0}
    for slot in range(1, pos.shape[0]):
        if np.allclose(pos[slot], np.asarray(layouts._PARKED)):
            continue
        kind = "box" if slot <= BOX_SLOTS else "capsule"
        counts[kind] += 1
        entry = {"type": kind, "name": f"{kind}_{counts[kind]}"}
        if kind == "box":
            with warnings.catch_warnings():   # gimbal lock (pitch +-90 degrees): roll is folded into yaw
                warnings.simplefilter("ignore", UserWarning)
                yaw, pitch, roll = Rotation.from_matrix(rot[slot]).as_euler("ZYX", degrees=True)
            entry.update(center=_round(pos[slot]), half_extents=_round(size[slot]),
                         yaw=_round([yaw])[0], pitch=_round([pitch])[0], roll=_round([roll])[0])
        else:
            axis = rot[slot][:, 2] * size[slot, 1]
            entry.update({"from": _round(pos[slot] - axis), "to": _round(pos[slot] + axis),
                          "radius": _round(size[slot, :1])[0]})
        solids.append(entry)
    data["solids"] = solids
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".json":
        path.write_text(json.dumps(data, indent=2) + "\n")
    else:
        path.write_text(yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120))
    return path
