"""`make_params`: the `EnvParams` of a scenario with keyword overrides, checked before anything is
built or compiled; an unknown name, a wrong type or an impossible value is a ValueError naming the
parameter and what is allowed.

The parameters themselves, each with its documentation and source, are declared in
`docrl_jax/envs/param_fields.py`; the env's modules import them through this module, beside the
function that checks them.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, Iterable

from docrl_jax import schema
from docrl_jax.envs.param_fields import (  # noqa: F401  (the env's modules import these from here)
    BOX_SLOTS, CAPSULE_SLOTS, HULL_REACH, HULL_SPHERE_PITCH, HULL_SPHERE_RADIUS, MAX_LATENCY, PAPER_OBS_SIZE,
    RANDOM_BOXES, RANDOM_CAPSULES, VEHICLE_FIELDS, VERTICAL_BEAMS, EnvParams, vehicle_overrides)


def param_docs() -> dict[str, str]:
    """Name -> documentation of every parameter (used by error messages and the README)."""
    return schema.field_docs(EnvParams)


# _fail(name, value, why) raises ValueError("env parameter NAME=VALUE: why"); the evaluator's CLI
# reads that prefix to name the key as typed.
_fail = functools.partial(schema.fail, prefix="env parameter ")


def validate(p: EnvParams) -> EnvParams:
    """Checks types and ranges; raises ValueError naming the parameter and what is allowed."""
    fields = {f.name: f for f in dataclasses.fields(EnvParams)}
    defaults = EnvParams()
    for name in fields:
        value, ref = getattr(p, name), getattr(defaults, name)
        if isinstance(ref, bool):
            if not isinstance(value, bool):
                _fail(name, value, "must be a bool (true/false)")
        elif isinstance(ref, int):
            if isinstance(value, bool) or not isinstance(value, int):
                _fail(name, value, "must be an integer")
        elif isinstance(ref, float):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                _fail(name, value, "must be a finite number")
        elif name == "substep_unroll":
            continue  # checked below
        elif name == "tank":
            if value is not None and not isinstance(value, str):
                _fail(name, value, "must be the path of a tank file or folder (a string), or None")
            continue
        elif isinstance(ref, tuple) or ref is None:
            if value is None and ref is None:
                continue
            n = len(ref) if isinstance(ref, tuple) else 2
            if (not isinstance(value, (tuple, list)) or len(value) != n
                    or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                               for v in value)):
                _fail(name, value, f"must be a sequence of {n} finite numbers")
    if p.scenario not in (0, 1, 2, 3):
        _fail("scenario", p.scenario, "valid scenarios are 0 (procedural), 1, 2, 3")
    _validate_ranges(p)
    if not 0 < p.physics_dt <= 0.01:
        _fail("physics_dt", p.physics_dt, "must be in (0, 0.01] s")
    if p.control_dt <= 0 or abs(p.substeps * p.physics_dt - p.control_dt) > 1e-9:
        _fail("control_dt", p.control_dt, f"must be a positive multiple of physics_dt={p.physics_dt}")
    if p.substep_unroll is not None and (isinstance(p.substep_unroll, bool) or not isinstance(p.substep_unroll, int)
                                         or p.substep_unroll < 1):
        _fail("substep_unroll", p.substep_unroll, "must be None or an integer >= 1")
    positive = ["max_episode_steps", "arrival_distance", "lidar_max_range", "sonar_max_range", "vel_p_gain",
                "rotor_max_thrust_air", "rotor_max_thrust_water", "rotor_tau_up", "rotor_tau_down",
                "water_density", "air_density", "hull_height", "wind_period", "lidar_fov_deg", "sonar_fov_deg",
                "max_forward_speed", "max_vertical_speed", "max_yaw_change", "max_tilt_deg"]
    for name in positive:
        if getattr(p, name) <= 0:
            _fail(name, getattr(p, name), "must be > 0")
    nonneg = ["collision_distance", "collision_margin", "hull_margin", "progress_reward_scale", "goal_clearance", "wall_margin",
              "lidar_min_range", "sensor_noise_std", "vel_i_gain", "vel_i_limit", "vel_i_band", "vel_i_rate",
              "rotor_moment_constant", "hull_volume", "wind_theta", "wind_sigma", "min_goal_distance"]
    if p.goal_clearance <= p.collision_distance + p.collision_margin:
        _fail("goal_clearance", p.goal_clearance, f"must exceed collision_distance + collision_margin = "
              f"{p.collision_distance + p.collision_margin:g} m, or a start or goal could be a collision")
    if p.hull_margin and p.goal_clearance <= HULL_REACH + p.hull_margin:
        _fail("goal_clearance", p.goal_clearance, f"must exceed the hull's reach {HULL_REACH:.3f} m + hull_margin = "
              f"{HULL_REACH + p.hull_margin:.3f} m, or a start or goal could be a collision")
    if p.max_goal_distance <= p.min_goal_distance:
        _fail("max_goal_distance", p.max_goal_distance, f"must exceed min_goal_distance={p.min_goal_distance}")
    for name in nonneg:
        if getattr(p, name) < 0:
            _fail(name, getattr(p, name), "must be >= 0")
    for name in ["att_gain", "rate_gain", "added_mass", "added_inertia", "water_linear_drag",
                 "water_quadratic_drag", "water_angular_drag", "air_linear_drag", "air_quadratic_drag"]:
        if any(v < 0 for v in getattr(p, name)):
            _fail(name, getattr(p, name), "entries must be >= 0")
    for name in ["start_water_fraction", "goal_water_fraction"]:
        if not 0.0 <= getattr(p, name) <= 1.0:
            _fail(name, getattr(p, name), "must be a probability in [0, 1]")
    if p.max_tilt_deg >= 80:
        _fail("max_tilt_deg", p.max_tilt_deg, "must be below 80 degrees")
    if isinstance(p.slant_beams, bool) or not isinstance(p.slant_beams, int) or p.slant_beams < 0:
        _fail("slant_beams", p.slant_beams, "must be an integer >= 0 (beams per ring; 0 = none)")
    if not 0 < p.slant_elevation_deg < 90:
        _fail("slant_elevation_deg", p.slant_elevation_deg, "must be in (0, 90) degrees")
    if p.lidar_fov_deg > 360 or p.sonar_fov_deg > 360:
        _fail("lidar_fov_deg/sonar_fov_deg", (p.lidar_fov_deg, p.sonar_fov_deg), "must be <= 360")
    lo, hi = p.bounds
    if not lo < 0 < hi:
        _fail("z_bounds", p.z_bounds, "must satisfy z_min < 0 (the surface) < z_max")
    for name, (a, b) in (("air_z_range", p.air_z_range), ("water_z_range", p.water_z)):
        if not a <= b:
            _fail(name, (a, b), "must be (low, high) with low <= high")
    if not (p.air_z_range[0] > 0 and p.air_z_range[1] < hi):
        _fail("air_z_range", p.air_z_range, f"must lie in (0, z_max={hi})")
    wz = p.water_z
    if not (wz[0] > lo and wz[1] < 0):
        _fail("water_z_range", wz, f"must lie in (z_min={lo}, 0)")
    return p



def _validate_ranges(p: EnvParams) -> None:
    """The (low, high) ranges of the procedural tanks and of the domain randomisation."""
    def ordered(name, lo_ok, hi_ok, why, integer=False):
        lo, hi = getattr(p, name)
        if integer and not all(isinstance(v, int) for v in (lo, hi)):
            _fail(name, (lo, hi), "must be (low, high) of whole numbers")
        if not (lo <= hi and lo_ok(lo) and hi_ok(hi)):
            _fail(name, (lo, hi), f"must be (low, high) with low <= high, {why}")

    ordered("layout_floor_top", lambda v: v >= -4.4, lambda v: v <= -0.8, "both in [-4.4, -0.8] m (the walls "
            "reach -4.6; the water band above the floor needs room)")
    ordered("layout_boxes", lambda v: v >= 0, lambda v: v <= RANDOM_BOXES,
            f"in [0, {RANDOM_BOXES}] (the random obstacles' box slots)", True)
    ordered("layout_capsules", lambda v: v >= 0, lambda v: v <= RANDOM_CAPSULES,
            f"in [0, {RANDOM_CAPSULES}] (the random obstacles' capsule slots)", True)
    if not 0.0 <= p.layout_structures <= 1.0:
        _fail("layout_structures", p.layout_structures, "must be a probability in [0, 1]")
    if p.tank is not None and p.scenario != 0:
        _fail("tank", p.tank, "tank files are tanks of scenario 0 (docrl_jax.envs.make(tank=PATH) sets it)")
    if not 0.0 <= p.layout_beam_fraction <= 1.0:
        _fail("layout_beam_fraction", p.layout_beam_fraction, "must be a probability in [0, 1]")
    ordered("dr_hull_volume_scale", lambda v: v >= 0, lambda v: v <= 100, "both in [0, 100] (0 = no buoyancy)")
    for name in ("dr_mass_scale", "dr_water_drag_scale", "dr_air_drag_scale",
                 "dr_added_mass_scale", "dr_thrust_air_scale", "dr_thrust_water_scale", "dr_motor_tau_scale",
                 "dr_wind_scale"):
        ordered(name, lambda v: v > 0, lambda v: v <= 100, "both in (0, 100] (a scale of the nominal value; "
                "(1, 1) = off)")
    ordered("dr_current_speed", lambda v: v >= 0, lambda v: v <= 2.0, "both in [0, 2] m/s")
    ordered("dr_range_noise_std", lambda v: v >= 0, lambda v: v <= 5.0, "both in [0, 5] m")
    ordered("dr_beam_dropout", lambda v: v >= 0, lambda v: v <= 1.0, "both probabilities in [0, 1]")
    for name in ("dr_action_latency", "dr_obs_latency"):
        ordered(name, lambda v: v >= 0, lambda v: v <= MAX_LATENCY, f"in [0, {MAX_LATENCY}] control steps", True)


def check_names(names: Iterable[str]) -> None:
    """Raises ValueError naming the first name that is no EnvParams field, the fields nearest it and where
    all are declared."""
    valid = param_docs()
    unknown = [n for n in names if n not in valid]
    if unknown:
        raise ValueError(f"unknown env parameter {schema.first_and_count(unknown)}; valid names: the fields of "
                         f"EnvParams in {schema.declared_in(EnvParams)}{schema.did_you_mean(unknown[0], valid)}")


def make_params(scenario: int = 2, **overrides: Any) -> EnvParams:
    """EnvParams for `scenario` with keyword overrides; an unknown name raises ValueError naming the
    nearest valid ones (`check_names`)."""
    check_names(overrides)
    clean = {k: tuple(v) if isinstance(v, list) else v for k, v in overrides.items()}
    # Accept ints where floats are documented (e.g. wind_sigma=1), reject other types in validate().
    defaults = EnvParams()
    for k, v in list(clean.items()):
        if isinstance(getattr(defaults, k), float) and isinstance(v, int) and not isinstance(v, bool):
            clean[k] = float(v)
    return validate(EnvParams(scenario=scenario, **clean))
