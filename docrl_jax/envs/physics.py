"""Vehicle physics in JAX: the cascaded low-level controller, the rotors and the medium forces.

The agent commands velocities, never forces (as in the original, orig 2.3). Every physics substep:

    controller:  velocity command -> desired force -> attitude -> body rates -> 4 rotor thrusts
    rotors:      first-order thrust lag and per-medium thrust limits
    medium:      buoyancy, drag (air relative to the wind, water relative to the current),
                 added mass; the resulting wrench goes to MuJoCo through `xfrc_applied`

MuJoCo integrates the free body under gravity plus that wrench. All functions are pure and
operate on one vehicle; the environment vmaps them.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from docrl_jax.envs.params import EnvParams

GRAVITY = 9.81

# Rotor layout (orig 2.2): arms at (+-0.19725, +-0.19725, 0.035) m, body x forward. Spin directions
# front_right ccw, back_left ccw, front_left cw, back_right cw; a ccw rotor pushes the body clockwise,
# so its yaw moment sign is -1.
ROTOR_POS = np.array([[0.19725, 0.19725, 0.035],     # front left, cw
                      [-0.19725, 0.19725, 0.035],    # back left, ccw
                      [-0.19725, -0.19725, 0.035],   # back right, cw
                      [0.19725, -0.19725, 0.035]],   # front right, ccw
                     dtype=np.float32)
ROTOR_YAW_SIGN = np.array([1.0, -1.0, 1.0, -1.0], dtype=np.float32)


class Plant(NamedTuple):
    """The vehicle and water the physics runs in one episode: the nominal values of `EnvParams`, or a
    draw of the domain randomisation (docrl_jax/envs/randomization.py). Only the physics reads it: the
    controller keeps the nominal model (`EnvParams`), so a drawn plant is a model mismatch. Leaves are
    scalars or (3,) arrays, batched under `vmap` like the rest of the state."""
    mass_scale: jnp.ndarray           # () true mass and inertia / the MJCF's
    buoyancy: jnp.ndarray             # () N at full immersion: water density x hull volume x g
    added_mass: jnp.ndarray           # (3,) kg, body axes
    added_inertia: jnp.ndarray        # (3,) kg m^2
    water_linear_drag: jnp.ndarray    # (3,)
    water_quadratic_drag: jnp.ndarray  # (3,)
    water_angular_drag: jnp.ndarray   # (3,)
    air_linear_drag: jnp.ndarray      # (3,)
    air_quadratic_drag: jnp.ndarray   # (3,)
    thrust_air: jnp.ndarray           # () N per rotor
    thrust_water: jnp.ndarray         # () N per rotor
    tau_up: jnp.ndarray               # () s
    tau_down: jnp.ndarray             # () s
    moment_constant: jnp.ndarray      # () m
    wind_sigma: jnp.ndarray           # () m/s OU noise per update
    current: jnp.ndarray              # (3,) m/s world frame
    noise_std: jnp.ndarray            # () m range noise
    dropout: jnp.ndarray              # () probability a beam reads its maximum
    action_latency: jnp.ndarray       # () int32 control steps
    obs_latency: jnp.ndarray          # () int32 control steps


class Vehicle(NamedTuple):
    """Constants of the rigid body, read from the MJCF model."""
    mass: float
    inertia: np.ndarray      # (3,) principal moments, body axes
    mixer_inv: np.ndarray    # (4, 4): [thrust, tau_x, tau_y, tau_z] -> rotor thrusts


def make_vehicle(mass: float, inertia: np.ndarray, moment_constant: float) -> Vehicle:
    x, y = ROTOR_POS[:, 0], ROTOR_POS[:, 1]
    mixer = np.stack([np.ones(4), y, -x, ROTOR_YAW_SIGN * moment_constant]).astype(np.float64)
    return Vehicle(float(mass), np.asarray(inertia, np.float32), np.linalg.inv(mixer).astype(np.float32))


def quat_to_mat(q: jnp.ndarray) -> jnp.ndarray:
    """Rotation matrix (body -> world) of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q / jnp.linalg.norm(q)
    return jnp.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def yaw_of(rot: jnp.ndarray) -> jnp.ndarray:
    return jnp.arctan2(rot[1, 0], rot[0, 0])


def submerged_fraction(z: jnp.ndarray, height: float) -> jnp.ndarray:
    """Fraction (0..1) of a body of `height` centred at `z` below the surface z = 0.

    A smoothstep of the linear immersion, so forces change with a continuous derivative as the hull
    crosses the surface (UUV's linear partial volume, orig 2.5, smoothed).
    """
    s = jnp.clip((0.5 * height - z) / height, 0.0, 1.0)
    return s * s * (3.0 - 2.0 * s)


def command_from_action(p: EnvParams, action: jnp.ndarray) -> jnp.ndarray:
    """[-1, 1]^3 -> (forward speed, vertical speed, dpsi), the original's mapping (orig 4.2)."""
    return jnp.array([(action[0] + 1.0) * 0.5 * p.max_forward_speed,
                      action[1] * p.max_vertical_speed,
                      action[2] * p.max_yaw_change])


def _vee(m: jnp.ndarray) -> jnp.ndarray:
    return jnp.array([m[2, 1], m[0, 2], m[1, 0]])


def _normalize(v: jnp.ndarray) -> jnp.ndarray:
    return v / jnp.maximum(jnp.linalg.norm(v), 1e-9)


def controller(p: EnvParams, veh: Vehicle, rot, vel, omega, frac, integral, command, dt):
    """Cascaded velocity controller in the manner of the RotorS Lee controller (orig 2.3).

    The original bridge sends the current pose as the position reference, so the position error is
    zero and only the velocity loop acts; the yaw reference is the current yaw with dpsi as yaw-rate
    reference, and the horizontal velocity points at yaw + dpsi. We add an integral term (so
    buoyancy and drag do not leave a steady error) and make the loop gains medium-aware through the
    vehicle's depth (a pressure sensor on a real HUAUV): the effective mass and inertia include the
    added mass in water, and feed-forward terms cancel the expected buoyancy and drag (translational
    and yaw) at the commanded velocity.

    Returns (rotor thrust commands (4,), new integral (3,)).
    """
    speed, vz, dpsi = command[0], command[1], command[2]
    yaw = yaw_of(rot)
    heading = yaw + dpsi
    v_cmd = jnp.array([speed * jnp.cos(heading), speed * jnp.sin(heading), vz])
    err = v_cmd - vel
    i_lim = p.vel_i_limit / max(p.vel_i_gain, 1e-6)
    # Conditional integration (anti-windup): the whole error near the setpoint; farther, at most
    # vel_i_rate (0: nothing), so a command step barely winds it up and a steady disturbance still does.
    # (vel_i_rate is static: at 0 this is the very program measured before the LSTM configs set 0.3.)
    outside = jnp.clip(err, -p.vel_i_rate, p.vel_i_rate) if p.vel_i_rate > 0 else 0.0
    integral = jnp.clip(integral + jnp.where(jnp.abs(err) < p.vel_i_band, err, outside) * dt, -i_lim, i_lim)

    m_eff = veh.mass + frac * float(np.mean(p.added_mass))
    force = m_eff * (p.vel_p_gain * err + p.vel_i_gain * integral)
    # Feed-forward of the drag expected at the commanded velocity (air drag is tiny; water drag is not),
    # so the integral only has to absorb model error and wind.
    v_cmd_b = rot.T @ v_cmd
    k_drag = (frac * (jnp.asarray(p.water_linear_drag) + jnp.asarray(p.water_quadratic_drag) * jnp.abs(v_cmd_b))
              + (1.0 - frac) * (jnp.asarray(p.air_linear_drag) + jnp.asarray(p.air_quadratic_drag) * jnp.abs(v_cmd_b)))
    force = force + rot @ (k_drag * v_cmd_b)
    # Feed-forward: weight minus the buoyancy the controller expects at its depth.
    buoyancy = frac * p.water_density * p.hull_volume * GRAVITY
    force = force + jnp.array([0.0, 0.0, veh.mass * GRAVITY - buoyancy])
    # Limit the tilt: keep some upward thrust and bound the horizontal part.
    fz = jnp.maximum(force[2], 0.2 * veh.mass * GRAVITY)
    fh = force[:2]
    fh_max = fz * np.tan(np.deg2rad(p.max_tilt_deg))
    fh = fh * jnp.minimum(1.0, fh_max / jnp.maximum(jnp.linalg.norm(fh), 1e-9))
    force = jnp.concatenate([fh, fz[None]])

    b3 = _normalize(force)
    b1c = jnp.array([jnp.cos(yaw), jnp.sin(yaw), 0.0])
    b2 = _normalize(jnp.cross(b3, b1c))
    b1 = jnp.cross(b2, b3)
    rot_des = jnp.stack([b1, b2, b3], axis=1)
    e_rot = 0.5 * _vee(rot_des.T @ rot - rot.T @ rot_des)
    e_omega = omega - jnp.array([0.0, 0.0, dpsi])
    inertia = jnp.asarray(veh.inertia)
    inertia_eff = inertia + frac * jnp.asarray(p.added_inertia)
    torque = (inertia_eff / inertia) * (-jnp.asarray(p.att_gain) * e_rot - jnp.asarray(p.rate_gain) * e_omega)
    torque = torque + jnp.cross(omega, inertia * omega)
    # Feed-forward of the water's rotational drag at the commanded yaw rate (same model as medium_wrench),
    # so the yaw rate is tracked without steady error underwater.
    k_yaw = p.water_angular_drag[2] * (1.0 + jnp.abs(dpsi))
    torque = torque + jnp.array([0.0, 0.0, frac * k_yaw * dpsi])
    thrust = jnp.dot(force, rot[:, 2])
    rotor_cmd = jnp.asarray(veh.mixer_inv) @ jnp.concatenate([thrust[None], torque])
    return rotor_cmd, integral


def rotor_limits(plant: Plant, position, rot) -> jnp.ndarray:
    """Per-rotor thrust limit, blended by each rotor's own immersion (rotor disk band 0.04 m)."""
    rotor_z = position[2] + (jnp.asarray(ROTOR_POS) @ rot.T)[:, 2]
    wet = submerged_fraction(rotor_z, 0.04)
    return (1.0 - wet) * plant.thrust_air + wet * plant.thrust_water


def rotor_response(plant: Plant, thrust, command, limit, dt) -> jnp.ndarray:
    """First-order motor lag (RotorS time constants, faster up than down), clipped to the limits."""
    command = jnp.clip(command, 0.0, limit)
    tau = jnp.where(command > thrust, plant.tau_up, plant.tau_down)
    return thrust + (command - thrust) * (1.0 - jnp.exp(-dt / tau))


def medium_wrench(plant: Plant, veh: Vehicle, rot, vel, omega, thrust, wind_xy, frac, dt) -> jnp.ndarray:
    """World-frame [force, torque] to put in `xfrc_applied` (MuJoCo adds gravity itself).

    Physical forces: rotor thrust and yaw moments; buoyancy rho_w * V * g * frac at the centre of mass
    (the original's centre of buoyancy); drag, linear + quadratic per body axis, blended between air
    (relative to the wind, so wind acts only in air) and water (relative to the current).

    Drag is applied in backward-Euler form, F = -k v / (1 + k dt / m), which is what an implicit step
    of dv/dt = -k v / m gives: unconditionally stable even for stiff water drag at high speed.

    Added mass: MuJoCo cannot change a body's mass per step, so we apply the force that gives the
    acceleration the heavier body would have: a = F_net / (m + frac * m_A) per body axis, then
    F_applied = m * a - m * g. The same for rotation with the added inertia. A plant whose mass differs
    from the MJCF's (domain randomisation) is the same device: its weight and inertia enter F_net and
    the effective mass, and MuJoCo's body keeps the MJCF's.
    """
    m = veh.mass
    inertia = jnp.asarray(veh.inertia)
    g_vec = jnp.array([0.0, 0.0, -GRAVITY])
    m_true = m * plant.mass_scale
    m_eff = m_true + frac * plant.added_mass                   # (3,) body axes
    inertia_eff = inertia * plant.mass_scale + frac * plant.added_inertia

    rotor_pos = jnp.asarray(ROTOR_POS)
    f_rot_b = jnp.array([0.0, 0.0, jnp.sum(thrust)])
    tau_rot_b = jnp.sum(jnp.cross(rotor_pos, jnp.stack([jnp.zeros(4), jnp.zeros(4), thrust], -1)), 0)
    tau_rot_b = tau_rot_b + jnp.array([0.0, 0.0, jnp.sum(ROTOR_YAW_SIGN * plant.moment_constant * thrust)])

    def drag(v_rel_world, lin, quad):
        v_b = rot.T @ v_rel_world
        k = jnp.asarray(lin) + jnp.asarray(quad) * jnp.abs(v_b)
        return -k * v_b / (1.0 + k * dt / m_eff)

    wind3 = jnp.array([wind_xy[0], wind_xy[1], 0.0])
    f_drag_b = (frac * drag(vel - plant.current, plant.water_linear_drag, plant.water_quadratic_drag)
                + (1.0 - frac) * drag(vel - wind3, plant.air_linear_drag, plant.air_quadratic_drag))
    k_ang = plant.water_angular_drag * (1.0 + jnp.abs(omega))   # linear + quadratic, UUV values
    tau_drag_b = -frac * k_ang * omega / (1.0 + frac * k_ang * dt / inertia_eff)

    f_buoy = jnp.array([0.0, 0.0, frac * plant.buoyancy])
    f_net = rot @ (f_rot_b + f_drag_b) + f_buoy + m_true * g_vec
    acc = rot @ ((rot.T @ f_net) / m_eff)
    force = m * acc - m * g_vec
    torque = rot @ (inertia * (tau_rot_b + tau_drag_b) / inertia_eff)
    return jnp.concatenate([force, torque])


def hover_thrust(p: EnvParams, veh: Vehicle, z) -> jnp.ndarray:
    """Per-rotor thrust that balances weight minus buoyancy at height z (level attitude)."""
    frac = submerged_fraction(z, p.hull_height)
    net = veh.mass * GRAVITY - frac * p.water_density * p.hull_volume * GRAVITY
    return jnp.full((4,), net / 4.0)
