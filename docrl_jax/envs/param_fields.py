"""Every documented parameter of the HUAUV environment, with its source or reasoning: `EnvParams`.

`EnvParams` is frozen and hashable: it is static configuration, read at trace time, so changing
a value recompiles. `docrl_jax.envs.make(scenario, **overrides)` builds one, checked by
`docrl_jax.envs.params.make_params` (which every env module imports these names through).
Sources: "orig" = the authors' released code (the section of our notes on it given),
"paper" = the DoCRL paper, "issue" = the project's environment contract.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from docrl_jax.schema import documented

Vec3 = tuple[float, float, float]
# The paper's observation (docrl_jax/envs/huauv.py lays it out) and the beams `vertical_beams` adds
# (`slant_beams` adds two rings of its own count).
PAPER_OBS_SIZE = 26
VERTICAL_BEAMS = 2
# The hull (a 0.47 x 0.47 x 0.09 m box) as the collision check sees it: spheres of HULL_SPHERE_RADIUS on a
# 3 x 3 grid of pitch HULL_SPHERE_PITCH in the body x-y plane (each radius reaches its grid cell's farthest
# corner, 0.119 m, rounded up). No point of the cover is farther than HULL_REACH from the body centre.
HULL_SPHERE_PITCH = 0.157
HULL_SPHERE_RADIUS = 0.12
HULL_REACH = math.sqrt(2.0) * HULL_SPHERE_PITCH + HULL_SPHERE_RADIUS
# Slots of assets/procedural.xml (a test checks the file against these): what one tank can hold, a
# tank file's solids included. The random obstacles of a procedural layout use the first RANDOM_BOXES
# and RANDOM_CAPSULES of them (their draws are those of the 12 + 6 slot scene, so every numbered layout
# is what it always was); structures and tank files use any.
BOX_SLOTS, CAPSULE_SLOTS = 24, 8
RANDOM_BOXES, RANDOM_CAPSULES = 12, 6
MAX_LATENCY = 10  # control steps (2 s): the queues are this long at most


@dataclass(frozen=True)
class EnvParams:
    # ---------------------------------------------------------------- task
    scenario: int = documented(2, "Tank layout: 1 empty, 2 four risers, 3 fifteen obstacles (orig 1.3); 0 = procedural: "
                                  "every episode draws its own layout (docrl_jax/envs/layouts.py, the layout_* "
                                  "parameters below).")
    control_dt: float = documented(0.2, "Seconds per agent step: 5 Hz, the rate of the original's sensors (orig 2.4).")
    physics_dt: float = documented(0.01, "Physics substep in seconds; must divide control_dt and be <= 0.01 "
                                         "(the original Gazebo max_step_size).")
    substep_unroll: int | None = documented(None,
        "Speed only: physics substeps XLA unrolls per loop iteration (same results for any value). None = 2 "
        "on GPU/TPU (a faster cold launch: docs/BENCHMARKS.md, \"Why the defaults are what they are\") and 1 on "
        "CPU (faster there).")
    max_episode_steps: int = documented(500, "Steps before truncation (paper: 500).")
    arrival_distance: float = documented(0.5, "Goal reached when the 3-D distance is below this (paper c_d = 0.5 m).")
    collision_distance: float = documented(0.5, "Collision when the smallest range is below this (paper c_o = 0.5 m).")
    collision_margin: float = documented(0.0,
        "Ours, training only: the training episodes end as collisions already when the smallest range is below "
        "collision_distance + this, so a policy learns to keep a margin from what its fan sees. Every "
        "evaluation (the trainer's, the evaluator's, the robustness benchmark's) runs without it.")
    hull_margin: float = documented(0.0,
        "Ours, training only: the training episodes also end as collisions when the hull comes within this "
        "distance (m) of an obstacle in any direction (the walls and the floor excepted: starts and goals may "
        "lie nearer to them), where the fan's range check sees only the body plane. 0 = off; every evaluation "
        "runs without it.")
    reward_arrive: float = documented(100.0, "Reward on arrival (paper r_arrive).")
    reward_collide: float = documented(-10.0, "Reward on collision or leaving the vertical bounds (paper r_collide).")
    reward_timeout: float = documented(-10.0, "Reward when the step limit is reached (paper: r_collide at ep = 500).")
    progress_reward_scale: float = documented(0.0, "Dense shaping: scale * (previous distance - distance) per step, "
                                                   "so moving towards the goal pays before the first arrival "
                                                   "does. 0 = the paper's binary reward.")
    terminate_on_arrival: bool = documented(False,
        "End the episode on arrival (evaluation). False = sample a new goal and "
        "go on from where the vehicle is (training, as in the paper).")
    z_bounds: tuple[float, float] | None = documented(None,
        "Vertical termination bounds (z_min, z_max). None = the original's (-1.1, 4.8), scenario 3 "
        "(floor + 0.2, 4.8) (orig 1.2).")

    # ---------------------------------------------------------------- starts and goals
    start_water_fraction: float = documented(0.5, "Probability that a training start is underwater.")
    goal_water_fraction: float = documented(0.5,
        "Probability that a training goal is underwater (the original sampled "
        "air goals only, orig 1.5, which cannot teach air-to-water).")
    goal_clearance: float = documented(1.0, "Starts and goals keep at least this distance (m) from every obstacle.")
    wall_margin: float = documented(0.6, "Starts and goals keep at least this distance (m) from the walls.")
    air_z_range: tuple[float, float] = documented((0.5, 4.0), "Heights (m) of air starts/goals (orig goals: 0.5-3.9).")
    water_z_range: tuple[float, float] | None = documented(None,
        "Depths (m) of underwater starts/goals. None = (z_min + 0.1, -0.3): the paper's evaluation "
        "target sits at -1.0, 0.1 m above the bound.")
    min_goal_distance: float = documented(1.0, "A sampled goal is at least this far (m) from the vehicle.")
    max_goal_distance: float = documented(100.0,
        "A sampled goal is at most this far (m) from the vehicle (curricula, easy "
        "tests); the default 100 never binds in the 10 m tank.")

    # ---------------------------------------------------------------- sensors
    lidar_fov_deg: float = documented(270.0, "LIDAR fan: beams at linspace(-fov/2, fov/2, 20) from body x (orig 3.1).")
    lidar_min_range: float = documented(0.5, "LIDAR minimum range (m), UST-10LX (orig 3.1). Documented only: "
                                             "closer returns are reported as measured so collisions are seen.")
    lidar_max_range: float = documented(10.0, "LIDAR maximum range (m); no hit reads this (orig 3.1).")
    sonar_fov_deg: float = documented(90.0, "Sonar fan width; 20 beams at linspace(-45, 45, 20) (orig 3.2).")
    sonar_max_range: float = documented(20.0, "Sonar maximum range (m); no hit reads this (orig 3.2).")
    sensor_noise_std: float = documented(0.0, "Std (m) of Gaussian range noise; 0 = noiseless (orig: 0).")
    vertical_beams: bool = documented(False,
        "Ours (not in the paper's state): two more beams of the active sensor along body +z and -z, an "
        "upward and a downward range finder, appended to the observation (28 floats). They see what the "
        "fans see (walls, floor, obstacles; not the water surface), so they show beams above or below "
        "the vehicle, which the horizontal fans miss. The collision check on ranges stays on the fans.")
    slant_beams: int = documented(0,
        "Ours (not in the paper's state): two rings of this many beams of the active sensor, slanted "
        "slant_elevation_deg above and below the body x-y plane at bearings k * 360 / n from body x, "
        "appended after the vertical beams (the upper ring, then the lower; 2 n more floats). They see "
        "what the fans see, so they show the edge of an obstacle the hull would clip while climbing or "
        "descending past it, which neither the fans nor the vertical beams catch. 0 = none.")
    slant_elevation_deg: float = documented(30.0, "Elevation of the slant_beams rings from the body x-y plane "
                                                  "(degrees, in (0, 90)).")

    # ---------------------------------------------------------------- command mapping (orig 2.3, 4.2)
    max_forward_speed: float = documented(0.25, "a0 = -1..1 maps to forward speed 0..this (m/s).")
    max_vertical_speed: float = documented(0.25, "a1 = -1..1 maps to vertical speed -this..this (m/s).")
    max_yaw_change: float = documented(0.25, "a2 = -1..1 maps to dpsi -this..this: heading offset of the horizontal "
                                             "velocity (rad) and yaw-rate reference (rad/s), as the original bridge.")

    # ---------------------------------------------------------------- low-level controller (orig 2.3)
    vel_p_gain: float = documented(2.26, "Velocity loop gain (1/s): Lee K_v 4.7 / mass 2.077.")
    vel_i_gain: float = documented(1.0, "Velocity integral gain (1/s^2). Not in the original (which drifted 0.1 m/s "
                                        "under its buoyancy); absorbs what the buoyancy and drag feed-forward miss "
                                        "(wind, model error).")
    vel_i_band: float = documented(0.03, "The integral only accumulates while |velocity error| < this (m/s): "
                                         "conditional anti-windup, so command steps do not overshoot.")
    vel_i_rate: float = documented(0.0, "Outside the band the integral still accumulates the error clipped to "
                                        "+-this (m/s): a rate-limited integrator that takes up a steady "
                                        "disturbance larger than the band (a wrong mass or buoyancy, a current) in "
                                        "seconds. 0 holds the integral outside the band (the paper and MLP configs, and "
                                        "every result before the LSTM configs set 0.3).")
    vel_i_limit: float = documented(3.0, "Clamp of the integral term's acceleration (m/s^2), anti-windup.")
    max_tilt_deg: float = documented(30.0, "Largest commanded tilt of the thrust axis (deg).")
    att_gain: Vec3 = documented((2.0, 2.3, 0.15), "Attitude gains (N m/rad), RotorS Lee attitude_gain (orig 2.3).")
    rate_gain: Vec3 = documented((0.4, 0.52, 0.18),
        "Body-rate gains (N m s/rad), RotorS Lee angular_rate_gain (orig 2.3).")

    # ---------------------------------------------------------------- rotors (orig 2.2)
    rotor_max_thrust_air: float = documented(28.9, "Per-rotor thrust limit in air (N): 8.54858e-6 * 1838^2.")
    rotor_max_thrust_water: float = documented(28.9,
        "Per-rotor thrust limit in water (N). The same aerial rotors drive the vehicle underwater "
        "(orig 2.5). A torque-limited motor spins sqrt(rho_w/rho_a) ~ 29x slower in water and so "
        "reaches the same thrust (thrust and torque both scale with rho*omega^2).")
    rotor_tau_up: float = documented(0.0125, "Rotor thrust time constant when rising (s), RotorS.")
    rotor_tau_down: float = documented(0.025, "Rotor thrust time constant when falling (s), RotorS.")
    rotor_moment_constant: float = documented(0.016, "Yaw moment per newton of thrust (m), RotorS.")

    # ---------------------------------------------------------------- medium (orig 2.5, mjx-notes 2.3)
    water_density: float = documented(1028.0, "kg/m^3, UUV fluid_density (orig 2.5).")
    air_density: float = documented(1.225, "kg/m^3, sea-level air.")
    hull_volume: float = documented(5e-5, "Displaced volume (m^3), UUV plugin volume (orig 2.5): 0.5 N of buoyancy, "
                                          "2.5 % of the weight.")
    hull_height: float = documented(0.1, "Height (m) over which buoyancy, drag and added mass blend in as the hull "
                                         "crosses z = 0 (UUV bounding box height 0.1).")
    added_mass: Vec3 = documented((1.93, 1.93, 1.93),
        "Translational added mass in water (kg, body axes), UUV (orig 2.5).")
    added_inertia: Vec3 = documented((0.0156, 0.03, 0.0166),
        "Rotational added inertia in water (kg m^2, body axes), UUV diagonal.")
    water_linear_drag: Vec3 = documented((0.0125, 0.0125, 0.0499),
        "Linear drag in water (N s/m, body axes), UUV linear_damping with the "
        "dissipative sign (orig 2.5).")
    water_quadratic_drag: Vec3 = documented((8.7, 8.7, 39.9),
        "Quadratic drag in water (N s^2/m^2, body axes) = rho_w/2 * Cd * A * fill. Sides: Cd 1.0, "
        "0.47 x 0.09 m, fill 0.4; top: Cd 1.17 (flat plate), 0.47 x 0.47 m, fill 0.3 (open frame). The "
        "UUV values (0.0125) are ~1000x below any real body of this size.")
    water_angular_drag: Vec3 = documented((0.0125, 0.0125, 0.0499),
        "Rotational drag in water (N m s/rad, body axes), UUV.")
    air_linear_drag: Vec3 = documented((0.25, 0.25, 0.0),
        "Linear drag in air (N s/m, body axes): RotorS rotor drag at hover "
        "(~0.25 N per m/s, orig 2.2), horizontal only.")
    air_quadratic_drag: Vec3 = documented((0.0104, 0.0104, 0.0475),
        "Quadratic drag in air: water_quadratic_drag * rho_a/rho_w.")
    wind: bool = documented(True, "Horizontal Ornstein-Uhlenbeck wind acting in air only (orig 2.6).")
    wind_theta: float = documented(0.15, "OU mean reversion per update (orig 2.6).")
    wind_sigma: float = documented(0.175, "OU noise per update (m/s) (orig 2.6).")
    wind_period: float = documented(1.0, "Seconds between wind updates (orig: 1 Hz).")
    water_current: Vec3 = documented((0.0, 0.0, 0.0),
        "Constant water current (m/s, world frame); the original's was zero.")

    # ---------------------------------------------------------------- procedural tanks (scenario 0, ours)
    # A layout is drawn per episode inside the compiled program (docrl_jax/envs/layouts.py): the
    # tank's walls, a floor at a random depth and a random number of boxes and capsules in the slots of
    # assets/procedural.xml, each a riser, a post, a wall panel or a beam, in air, water or both.
    layout_floor_top: tuple[float, float] = documented((-2.0, -1.3),
        "Range (m) of the floor's top: scenarios 1-2 have -1.3, scenario 3 -2.0. The lower bound is the "
        "floor + 0.2 (as in every scenario).")
    layout_boxes: tuple[int, int] = documented((3, 10),
        "Range of the number of random boxes (posts, wall panels, beams); at most 12.")
    layout_capsules: tuple[int, int] = documented((1, 5),
        "Range of the number of random capsules (risers of radius 0.2-0.6 m, tilted or horizontal bars); at "
        "most 6.")
    layout_beam_fraction: float = documented(0.35,
        "Probability that a box or capsule is a horizontal/tilted beam at a random height instead of "
        "standing on the floor.")
    layout_structures: float = documented(0.0,
        "Probability that a procedural layout also holds structures a person builds into a tank: a wall "
        "across the tank with one opening, a ceiling with one way through, a room with a door, a dead end, "
        "a grove (docrl_jax/envs/structures.py); its start and goal regions then lie on either side. "
        "0 = today's random obstacles only.")
    tank: str | None = documented(None,
        "A tank file, or a folder of them (docs/TANKS.md): every episode flies in one of these tanks, drawn "
        "per episode, with its start and goal regions, instead of the scenario's (scenario 0 only). None = "
        "the scenario's tank.")
    layout_held_out: bool = documented(False,
        "True: episodes draw from the held-out layouts (ids 0 .. layouts.HELD_OUT_IDS - 1, the robustness "
        "benchmark's); False: from the training ids, which never include those.")

    # ---------------------------------------------------------------- domain randomisation (ours)
    # Per episode, the physics runs a plant drawn from these ranges (docrl_jax/envs/randomization.py);
    # the controller keeps the nominal model above. Scales multiply the nominal value; (1, 1) and
    # (0, 0) = off, the default everywhere.
    dr_mass_scale: tuple[float, float] = documented((1.0, 1.0), "Vehicle mass and inertia x U(range).")
    dr_hull_volume_scale: tuple[float, float] = documented((1.0, 1.0),
        "Displaced volume (buoyancy) x U(range); nominal buoyancy is 2.5 % of the weight.")
    dr_water_drag_scale: tuple[float, float] = documented((1.0, 1.0),
        "Every water drag coefficient (linear, quadratic, angular) x U(range).")
    dr_air_drag_scale: tuple[float, float] = documented((1.0, 1.0), "Every air drag coefficient x U(range).")
    dr_added_mass_scale: tuple[float, float] = documented((1.0, 1.0), "Added mass and added inertia x U(range).")
    dr_thrust_air_scale: tuple[float, float] = documented((1.0, 1.0), "Rotor thrust limit in air x U(range).")
    dr_thrust_water_scale: tuple[float, float] = documented((1.0, 1.0), "Rotor thrust limit in water x U(range).")
    dr_motor_tau_scale: tuple[float, float] = documented((1.0, 1.0),
        "Rotor time constants (rising and falling) x U(range): motor lag.")
    dr_wind_scale: tuple[float, float] = documented((1.0, 1.0),
        "Wind gusts: the OU noise wind_sigma x U(range) (the stationary wind std scales alike).")
    dr_current_speed: tuple[float, float] = documented((0.0, 0.0),
        "Speed (m/s) of an extra water current, U(range), in a uniformly random direction in 3-D (added "
        "to water_current).")
    dr_range_noise_std: tuple[float, float] = documented((0.0, 0.0),
        "Extra range noise std (m), U(range), added to sensor_noise_std for the episode.")
    dr_beam_dropout: tuple[float, float] = documented((0.0, 0.0),
        "Probability, U(range), that a beam reads the sensor's maximum range on a step (a lost return).")
    dr_action_latency: tuple[int, int] = documented((0, 0),
        "Whole control steps, uniform integer in the range, between the agent's action and the controller "
        "acting on it (hover until the first arrives).")
    dr_obs_latency: tuple[int, int] = documented((0, 0),
        "Whole control steps, uniform integer in the range, by which the observation is late.")

    # ------------------------------------------------------------------------------------------
    @property
    def substeps(self) -> int:
        return int(round(self.control_dt / self.physics_dt))

    @property
    def bounds(self) -> tuple[float, float]:
        if self.z_bounds is not None:
            return tuple(self.z_bounds)
        # Procedural tanks: the loosest bound here; each episode's own is its floor + 0.2 (layouts.py).
        floor_top = {3: -2.0, 0: self.layout_floor_top[0]}.get(self.scenario, -1.3)
        return (floor_top + 0.2, 4.8)

    @property
    def observation_size(self) -> int:
        """Floats in an observation: the paper's 26, plus the vertical and slanted beams that are on."""
        return PAPER_OBS_SIZE + VERTICAL_BEAMS * self.vertical_beams + 2 * self.slant_beams

    @property
    def water_z(self) -> tuple[float, float]:
        return self.water_band(self.bounds[0])

    def water_band(self, z_min):
        """Depths (low, high) of underwater starts/goals above the lower bound `z_min` (a number, or
        a traced scalar: a procedural tank's own bound)."""
        if self.water_z_range is not None:
            return tuple(self.water_z_range)
        return (z_min + 0.1, -0.3)


# The vehicle a trained policy is bound to: its control and physics steps, its sensors' geometry, the
# command mapping, the controller, the rotors and the hull in its media. A run trained with any of these
# changed is evaluated, benchmarked and rendered in that vehicle (`vehicle_overrides`); everything else
# (the tank, starts and goals, rewards, wind, currents, sensor noise, the randomisation ranges) is the
# test's to set, so every policy meets the same trials.
VEHICLE_FIELDS = frozenset({
    "control_dt", "physics_dt",
    "lidar_fov_deg", "lidar_min_range", "lidar_max_range", "sonar_fov_deg", "sonar_max_range", "vertical_beams",
    "slant_beams", "slant_elevation_deg",
    "max_forward_speed", "max_vertical_speed", "max_yaw_change",
    "vel_p_gain", "vel_i_gain", "vel_i_band", "vel_i_rate", "vel_i_limit", "max_tilt_deg", "att_gain", "rate_gain",
    "rotor_max_thrust_air", "rotor_max_thrust_water", "rotor_tau_up", "rotor_tau_down", "rotor_moment_constant",
    "water_density", "air_density", "hull_volume", "hull_height", "added_mass", "added_inertia",
    "water_linear_drag", "water_quadratic_drag", "water_angular_drag", "air_linear_drag", "air_quadratic_drag",
})


def vehicle_overrides(env_overrides: dict[str, Any]) -> dict[str, Any]:
    """The entries of a run's env overrides (its config's `env:` section) that change the vehicle."""
    return {k: v for k, v in env_overrides.items() if k in VEHICLE_FIELDS}

