"""The behaviour-based baseline (BBA) of the DoCRL paper, as the authors adapted it, in pure JAX.

The paper cites Marino et al. (2016) for its BBA; what the authors actually ran is their
`scripts/bug_algorithm.py`, a Bug-2-like wall follower driven through the same velocity bridge as
the agents (the authors' released code). That script is a sequence of blocking
loops; here it is a small state machine in the policy carry, one 0.2 s control step per `act`
call, with every branch computed and selected by `jnp.where` (jit/vmap-safe, no Python control
flow on traced values).

Phases of the original, one mode each here:

    GO_FORWARD (0)  `rotate` + `go_forward`: if the heading error to the target exceeds 0.1 rad,
                    turn in place at dpsi = +-0.25 (v = 0); otherwise fly forward at v = 0.25, dpsi = 0.
                    xy-distance < 0.5 m ends the horizontal phase; any range < 0.9 m means blocked
                    -> CONTOUR.
    CONTOUR (1)     `rotate_to_contour`: by the bearing a of the nearest return,
                    -135 deg < a < -90 deg: (v 0.15, dpsi -0.25);  -90 < a < -45: (0.15, +0.25);
                    otherwise (0, +0.25), i.e. turn left in place until the obstacle lies on the
                    right, then move along it. Leaves when every beam within +-45 deg of the target
                    bearing reads more than the xy-distance to the target -> GO_TO_TARGET.
    GO_TO_TARGET (2) `go_to_target`: like GO_FORWARD but with no obstacle check, until xy < 0.5 m.
    DEPTH (3)       `check_z_position`: vz = +-0.25 (v = 0, dpsi = 0) until |dz| < 0.1 m.
    HOLD (4)        all zero; the evaluator's environment decides arrival (3-D distance < 0.5 m).

Thresholds and where they come from (all from bug_algorithm.py unless stated):
    heading tolerance 0.1 rad, turn rate 0.25 (the `rotate` loop);
    horizontal arrival 0.5 m in x-y (`go_forward`/`go_to_target`; z is commented out there);
    blocked 0.9 m on the minimum of all ranges (`go_forward`);
    contour commands (0.15, -+0.25) / (0, +0.25) and the -135/-90/-45 deg sectors (the 1080-beam
    indices 0/180/360 at 4 beams per degree, 540 = straight ahead);
    contour exit cone +-45 deg (indices id_target -+ 180) against the xy-distance to the target,
    looked at only while the target bearing lies inside the active fan (see Deviations);
    depth tolerance 0.1 m and vz = +-0.25 m/s (`check_z_position`).
Commands are physical (m/s, rad) and are mapped to the env's [-1, 1] actions with the env's
`max_forward_speed`, `max_vertical_speed`, `max_yaw_change` (all 0.25: so v = 0.25 is a0 = 1,
v = 0 is a0 = -1, v = 0.15 is a0 = 0.2).

Deviations, and why:
  * Sensor. The original read the 270 deg LIDAR only, even underwater (Gazebo rays ignore water).
    Here only the active sensor is measured, so underwater the BBA sees the +-45 deg sonar fan:
    it reads `info["ranges"]` with the beam bearings of the active fan. Underwater the nearest return
    always lies in the "otherwise" sector, so contouring there is turning left in place until the
    +-45 deg cone towards the target is clear within the fan.
  * Beam indices. The original's 1080-beam index arithmetic (which, with the 20-beam LIDAR its launch
    file actually loaded, sliced meaningless ranges and had its exceptions swallowed) is replaced
    by the same rules on beam bearings: the sectors and the cone are angles, so they mean what the
    1080-beam code meant, for either fan.
  * Contour exit with the target outside the fan. In the original, id_target is clamped to
    [0, 1080]; for a target bearing below -90 deg the slice [id_target-180 : id_target+180] starts at
    a negative index, Python reads it from the end, the slice is empty, min() raises and the bare
    `except: pass` keeps contouring; above +90 deg the slice is merely truncated, so a target behind
    the vehicle (clamped to 1080) could count as "clear" on the 90-135 deg beams. Here one symmetric
    rule: the cone counts as clear only while the target bearing lies inside the active fan
    (+-135 deg LIDAR, +-45 deg sonar), and then on the fan's beams within +-45 deg of it.
  * Heading. `rotate` compared raw yaw - goal angle without wrapping (it could turn the long way
    round); here the error is wrapped to [-pi, pi] and the turn takes the short way.
  * Depth order. `depth_phase="after"` (default) is the DoCRL script's order as the authors' released script
    runs it: the whole horizontal phase at the start altitude, then the vertical one.
    `"first"` is the order of the JINT copy of the script (check_z_position before the horizontal
    phase; that copy is the one we could read), `"concurrent"` commands vz towards the target depth
    in every mode, and `"in_air"` (ours) climbs first when the target is above and descends last
    when it is below, so the horizontal phase always runs in air with the 270 deg LIDAR, the sensor
    the original relied on in both media.
  * After the depth phase (HOLD), a vehicle that has drifted more than 0.5 m from the target in x-y
    (wind during the descent) goes back to GO_FORWARD, and one that has lost the depth back to DEPTH.
    The original declared success after check_z_position without looking; here success is the
    environment's 3-D arrival (0.5 m), so the BBA keeps going until then or until the trial ends.
  * Episode accounting. The original ended a trial itself on a LIDAR reading < 0.7 m (0.6 in the
    JINT copy); here the environment decides collisions (0.5 m, plus hull contact) like for every
    other method.
  * Rate. The original's loops ran at the odometry rate (~100 Hz, with sensor data at 5-10 Hz);
    here a decision is taken once per 0.2 s control step, like the agents'.
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from docrl_jax.envs.sensors import beam_angles
from docrl_jax.policy import Policy

GO_FORWARD, CONTOUR, GO_TO_TARGET, DEPTH, HOLD = 0, 1, 2, 3, 4
MODE_NAMES = ("go_forward", "contour", "go_to_target", "depth", "hold")
DEPTH_PHASES = ("after", "first", "concurrent", "in_air")


def label(depth_phase: str = "after") -> str:
    """The method's name in tables and videos: "BBA", or "BBA (first)" for another depth phase."""
    return "BBA" if depth_phase == "after" else f"BBA ({depth_phase})"


@dataclass(frozen=True)
class BBAParams:
    """Thresholds of the original bug_algorithm.py (see the module docstring for each source)."""
    heading_tolerance: float = 0.1     # rad, `rotate`
    turn_rate: float = 0.25            # dpsi while rotating / contouring
    forward_speed: float = 0.25        # m/s, `go_forward`
    contour_speed: float = 0.15        # m/s, `rotate_to_contour`
    xy_tolerance: float = 0.5          # m, horizontal arrival
    blocked_distance: float = 0.9      # m, min(ranges) that stops go_forward
    cone_half_angle_deg: float = 45.0  # contour exit cone (+-180 of 1080 beams)
    rear_sector_deg: tuple[float, float] = (-135.0, -90.0)   # indices (0, 180): turn right
    front_sector_deg: tuple[float, float] = (-90.0, -45.0)   # indices (180, 360): turn left
    depth_tolerance: float = 0.1       # m, `check_z_position`
    vertical_speed: float = 0.25       # m/s, `check_z_position`
    depth_phase: str = "after"         # "after" (DoCRL order), "first" (JINT order), "concurrent", "in_air"
    # Env constants needed to read ranges and to map commands to actions (EnvParams defaults).
    lidar_fov_deg: float = 270.0
    sonar_fov_deg: float = 90.0
    max_forward_speed: float = 0.25
    max_vertical_speed: float = 0.25
    max_yaw_change: float = 0.25

    def __post_init__(self):
        if self.depth_phase not in DEPTH_PHASES:
            raise ValueError(f"depth_phase {self.depth_phase!r}: valid choices are {', '.join(DEPTH_PHASES)}")


def _wrap(a):
    return jnp.arctan2(jnp.sin(a), jnp.cos(a))


def make_bba(env_params=None, **overrides) -> Policy:
    """The BBA as a `Policy`. `env_params` (an EnvParams) supplies the sensor fans and action scales."""
    if env_params is not None:
        for name in ("lidar_fov_deg", "sonar_fov_deg", "max_forward_speed", "max_vertical_speed", "max_yaw_change"):
            overrides.setdefault(name, getattr(env_params, name))
    bp = BBAParams(**overrides)
    lidar_angles = beam_angles(bp.lidar_fov_deg)
    sonar_angles = beam_angles(bp.sonar_fov_deg)
    cone = np.deg2rad(bp.cone_half_angle_deg)
    rear = np.deg2rad(bp.rear_sector_deg)
    front = np.deg2rad(bp.front_sector_deg)
    initial_mode = DEPTH if bp.depth_phase == "first" else GO_FORWARD

    def init_carry():
        # "in_air" picks its first mode on the first step (it needs the goal): flagged by mode -1.
        mode = -1 if bp.depth_phase == "in_air" else initial_mode
        return {"mode": jnp.asarray(mode, jnp.int32), "horizontal_done": jnp.asarray(False)}

    def to_action(v, vz, dpsi):
        return jnp.stack([jnp.clip(2.0 * v / bp.max_forward_speed - 1.0, -1.0, 1.0),
                          jnp.clip(vz / bp.max_vertical_speed, -1.0, 1.0),
                          jnp.clip(dpsi / bp.max_yaw_change, -1.0, 1.0)]).astype(jnp.float32)

    def act(params, carry, obs, info, key):
        del params, obs, key
        pos, goal, yaw = info["position"], info["goal"], info["yaw"]
        ranges = info["ranges"]
        angles = jnp.where(info["underwater"], sonar_angles, lidar_angles)
        rel = goal - pos
        xy_dist = jnp.linalg.norm(rel[:2])
        dz = rel[2]
        heading_err = _wrap(jnp.arctan2(rel[1], rel[0]) - yaw)

        # ---- transitions (the loop conditions of the original, checked at the top of each step)
        mode, h_done = carry["mode"], carry["horizontal_done"]
        # "in_air": climb first when the target is above (the horizontal phase then runs in air with
        # the 270 deg LIDAR), descend last when it is below.
        mode = jnp.where(mode < 0, jnp.where(dz > 0, DEPTH, GO_FORWARD), mode)
        xy_ok = xy_dist < bp.xy_tolerance
        z_ok = jnp.abs(dz) < bp.depth_tolerance
        blocked = jnp.min(ranges) < bp.blocked_distance
        in_cone = jnp.abs(_wrap(angles - heading_err)) <= cone
        half_fov = jnp.where(info["underwater"], np.deg2rad(bp.sonar_fov_deg / 2), np.deg2rad(bp.lidar_fov_deg / 2))
        target_in_fan = jnp.abs(heading_err) <= half_fov
        cone_clear = target_in_fan & jnp.any(in_cone) & jnp.all(jnp.where(in_cone, ranges > xy_dist, True))

        # GO_FORWARD / GO_TO_TARGET: xy reached -> DEPTH (horizontal phase done); GO_FORWARD blocked -> CONTOUR
        horizontal = (mode == GO_FORWARD) | (mode == GO_TO_TARGET)
        new_mode = jnp.where(horizontal & xy_ok, DEPTH, mode)
        h_done = h_done | (horizontal & xy_ok)
        new_mode = jnp.where((mode == GO_FORWARD) & ~xy_ok & blocked, CONTOUR, new_mode)
        # CONTOUR: cone towards the target clear -> GO_TO_TARGET
        new_mode = jnp.where((mode == CONTOUR) & cone_clear, GO_TO_TARGET, new_mode)
        # DEPTH: depth reached -> HOLD if the horizontal phase is done, else start it
        new_mode = jnp.where((mode == DEPTH) & z_ok, jnp.where(h_done, HOLD, GO_FORWARD), new_mode)
        # HOLD: drifted out of the xy tolerance -> horizontal phase again; depth lost -> DEPTH
        drifted = (mode == HOLD) & ~xy_ok
        new_mode = jnp.where(drifted, GO_FORWARD, new_mode)
        h_done = h_done & ~drifted
        new_mode = jnp.where((mode == HOLD) & xy_ok & ~z_ok, DEPTH, new_mode)
        mode = new_mode.astype(jnp.int32)

        # ---- commands of the mode now active
        turn = jnp.where(heading_err > 0, bp.turn_rate, -bp.turn_rate)
        aligned = jnp.abs(heading_err) <= bp.heading_tolerance
        v_h = jnp.where(aligned, bp.forward_speed, 0.0)        # rotate in place, else straight on
        dpsi_h = jnp.where(aligned, 0.0, turn)

        nearest = angles[jnp.argmin(ranges)]
        in_rear = (nearest > rear[0]) & (nearest < rear[1])
        in_front = (nearest > front[0]) & (nearest < front[1])
        v_c = jnp.where(in_rear | in_front, bp.contour_speed, 0.0)
        dpsi_c = jnp.where(in_rear, -bp.turn_rate, bp.turn_rate)

        vz_d = jnp.where(z_ok, 0.0, jnp.sign(dz) * bp.vertical_speed)

        v = jnp.select([mode == GO_FORWARD, mode == CONTOUR, mode == GO_TO_TARGET], [v_h, v_c, v_h], 0.0)
        dpsi = jnp.select([mode == GO_FORWARD, mode == CONTOUR, mode == GO_TO_TARGET], [dpsi_h, dpsi_c, dpsi_h], 0.0)
        vz = jnp.where(mode == DEPTH, vz_d, 0.0)
        if bp.depth_phase == "concurrent":
            vz = vz_d
        return {"mode": mode, "horizontal_done": h_done}, to_action(v, vz, dpsi)

    return Policy(name="bba", params={}, init_carry=init_carry, act=act)
