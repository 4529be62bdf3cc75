"""The HUAUV navigation environment: pure `reset`, `reset_to` and `step` over an `EnvState` pytree.

One control step (0.2 s) = sanitise the action, update the wind, run `substeps` physics steps
(controller -> rotors -> medium wrench -> `mjx.step`), cast the active sensor fan once, then decide
collision, bounds, arrival, reward and the observation.

Observation layout (26 floats), see `OBS_LAYOUT`:
    0-19  ranges / active sensor's maximum range (LIDAR 10 m in air, sonar 20 m underwater)
    20-22 the action applied on this step, in [-1, 1] (zeros after reset)
    23    bearing of the goal in the x-y plane relative to yaw, / pi, in [-1, 1]
    24    elevation angle of the goal, / (pi / 2), in [-1, 1]
    25    3-D distance to the goal / DIST_SCALE (the tank's diagonal), clipped to [0, 1]
    26-27 with `vertical_beams` only: the ranges up and down (body +z, -z) / the active sensor's maximum
    then, with `slant_beams` n: the upper ring's n ranges, then the lower ring's, / the same maximum
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct

from docrl_jax.envs._quiet_import import mjx  # mujoco.mjx, without its notice about the optional Warp backend
# structures is imported here, not on first use: a first import while a program traces would run its
# module-level code inside that trace.
from docrl_jax.envs import geometry, layouts, physics, randomization, sensors, structures
from docrl_jax.envs.params import PAPER_OBS_SIZE, EnvParams, MAX_LATENCY
from docrl_jax.resources import resource_dir

OBS_SIZE = PAPER_OBS_SIZE   # with vertical_beams: 28 (`env.observation_size`, `EnvParams.observation_size`)
ACTION_SIZE = 3
DIST_SCALE = float(np.sqrt(9.8**2 + 9.8**2 + 6.1**2))  # inner tank diagonal, 15.14 m
OBS_LAYOUT = {"ranges": slice(0, 20), "prev_action": slice(20, 23), "bearing": 23, "elevation": 24,
              "distance": 25, "vertical": slice(26, 28),   # "vertical": with vertical_beams only
              "extra_beams": slice(26, None)}   # every range after the paper's 26: vertical, then slanted


GOAL_FEATURES = slice(sensors.NUM_BEAMS + ACTION_SIZE, sensors.NUM_BEAMS + ACTION_SIZE + 3)  # where they sit in obs


def goal_features(position, yaw, goal) -> jax.Array:
    """The observation's three goal floats (obs[GOAL_FEATURES]): the goal's bearing from the heading / pi,
    its elevation / (pi / 2), its distance / DIST_SCALE capped at 1."""
    rel = goal - position
    bearing = jnp.arctan2(rel[1], rel[0]) - yaw
    bearing = jnp.arctan2(jnp.sin(bearing), jnp.cos(bearing))
    elevation = jnp.arctan2(rel[2], jnp.linalg.norm(rel[:2]))
    return jnp.stack([bearing / jnp.pi, elevation / (jnp.pi / 2), jnp.minimum(jnp.linalg.norm(rel) / DIST_SCALE, 1.0)])


def observation_bounds(size: int = OBS_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """(low, high) of each of `size` observation floats (an env's `observation_size`): the ranges, the
    distance and the extra beams' ranges in [0, 1], the rest in [-1, 1]."""
    low = -np.ones(size, np.float32)
    for name in ("ranges", "distance", "extra_beams"):
        low[OBS_LAYOUT[name]] = 0.0
    return low, np.ones(size, np.float32)


def _one_env(method: str, name: str, x: jax.Array, shape: tuple, size_name: str = "") -> jax.Array:
    """The env's functions take one env's arrays; a wrong shape would otherwise broadcast or slice
    silently (a (2,) action gave a (25,) observation). Checked at trace time, so it costs nothing
    under jit. Raises ValueError naming the argument, both shapes and the fix for a batch."""
    if x.shape != shape:
        expected = f"{shape} = {size_name}" if size_name else f"{shape}"
        raise ValueError(f"env.{method}: {name} has shape {x.shape}, expected {expected} for one env; "
                         f"for a batch of envs, jax.vmap(env.{method}) over the leading axis")
    return x


@struct.dataclass
class SimState:
    """Internal state carried between steps (not part of the observation)."""
    data: mjx.Data            # MuJoCo state of the scene
    thrust: jax.Array         # (4,) rotor thrusts (N)
    vel_integral: jax.Array   # (3,) controller integrator
    wind: jax.Array           # (2,) horizontal wind (m/s)
    goal: jax.Array           # (3,)
    step: jax.Array           # () int32 steps since reset
    key: jax.Array            # PRNG key for noise, wind and goal resampling
    plant: physics.Plant      # the episode's true vehicle, water and sensors (domain randomisation)
    layout: Any               # layouts.Layout of a procedural tank (scenario 0); None otherwise
    actions: jax.Array        # (L, 3) the agent's last L actions, newest first (action latency; L may be 0)
    observations: jax.Array   # (L, obs size) the last L observations, newest first (observation latency)
    training_margins: jax.Array  # () bool: env.collision_margin and env.hull_margin end this episode. Set at
                                 # reset where the env has them; the trainer's evaluation lanes clear it,
                                 # so they fly the training env's step under the test's rules


@struct.dataclass
class EnvState:
    """One env's state between control steps (a frozen pytree: stack or vmap it for a batch). `obs` is what
    the policy sees next, `reward`/`done` describe the step that produced this state, `info` holds the
    episode's diagnostics (arrived, collision, out_of_bounds, truncated, distance, goal, ...)."""
    sim: SimState
    obs: jax.Array            # (26,), (28,) with vertical_beams
    reward: jax.Array         # ()
    done: jax.Array           # () bool
    info: dict[str, Any]


def scene_path(scenario: int) -> str:
    return str(resource_dir("assets") / (layouts.SCENE if scenario == 0 else f"scenario_{scenario}.xml"))


class HUAUVEnv:
    """Build with `docrl_jax.envs.make(scenario, **overrides)`. Methods are pure and jit/vmap-safe."""

    action_size = ACTION_SIZE

    def __init__(self, params: EnvParams):
        self.params = params
        self.observation_size = params.observation_size
        self.mj_model = mujoco.MjModel.from_xml_path(scene_path(params.scenario))
        self.mj_model.opt.timestep = params.physics_dt
        # This process's first device: MJX's default, jax.devices()[0], belongs to process 0 in a
        # multi-process run (docrl_jax.sharding); on one process the two are the same.
        device = jax.local_devices()[0]
        self.mjx_model = mjx.put_model(self.mj_model, device=device)
        self.body_id = self.mj_model.body("huauv").id
        self.vehicle = physics.make_vehicle(self.mj_model.body_mass[self.body_id],
                                            self.mj_model.body_inertia[self.body_id],
                                            params.rotor_moment_constant)
        self.procedural = params.scenario == 0
        # A tank set (params.tank: tank files, docrl_jax/envs/tanks.py): a Layout stacked over its tanks.
        self.tanks = None
        if self.procedural:  # walls from the MJCF; floor and obstacles from each episode's layout
            self.walls = geometry.solids_from_model(self.mj_model, "walls")
            self.slot_ids = layouts.slot_ids(self.mj_model)
            if params.tank is not None:
                from docrl_jax.envs import tanks
                self.tanks = tanks.load_set(params.tank, params)
        else:
            self.boundary = geometry.solids_from_model(self.mj_model, "boundary")
            self.obstacles = geometry.solids_from_model(self.mj_model, "obstacles")
        # Queue lengths of the latencies (static: the largest delay the ranges allow).
        self._action_queue = max(params.dr_action_latency)
        self._obs_queue = max(params.dr_obs_latency)
        assert max(self._action_queue, self._obs_queue) <= MAX_LATENCY
        # Template with the static geoms placed (rays read their poses from Data): MuJoCo's own
        # mj_forward on the CPU, then put on the device. Equal, leaf for leaf, to jit(mjx.forward) of
        # mjx.make_data, without compiling a program at every env build (seconds of start-up).
        mj_data = mujoco.MjData(self.mj_model)
        mujoco.mj_forward(self.mj_model, mj_data)
        self._data0 = mjx.put_data(self.mj_model, mj_data, device=device)
        self._wind_every = max(1, int(round(params.wind_period / params.control_dt)))
        # physics substeps unrolled per scan iteration (params.substep_unroll, or the backend's best)
        self.substep_unroll = params.substep_unroll or (1 if jax.default_backend() == "cpu" else 2)

    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per `step` (the policy's control period)."""
        return self.params.control_dt

    # ------------------------------------------------------------------ the episode's tank
    def solids(self, layout=None):
        """(obstacles, for the start/goal sampler and the hull check; the walls and the floor, for the
        hull check; lower z bound)."""
        if not self.procedural:
            return self.obstacles, self.boundary, self.params.bounds[0]
        z_min = layout.z_min if self.params.z_bounds is None else self.params.bounds[0]
        return layouts.obstacles(layout), layouts.boundary(layout, self.walls), z_min

    def _cast(self, data, layout, position, rot, underwater):
        """Noise-free ranges of the active fan (then the vertical beams, if on), against the episode's tank."""
        model = self.mjx_model
        if self.procedural:
            model, data = layouts.place(model, data, layout, self.slot_ids)
        return sensors.cast(self.params, model, data, self.body_id, position, rot, underwater)

    def _sense(self, data, layout, plant, key, position, rot, underwater):
        """(the fan's noise-free ranges, for the collision check; what the sensors report: the fan, then
        the vertical beams if on)."""
        true_ranges = self._cast(data, layout, position, rot, underwater)
        return true_ranges[:sensors.NUM_BEAMS], sensors.corrupt(self.params, plant, key, true_ranges, underwater)

    # ------------------------------------------------------------------ sampling
    def draw_layout(self, key: jax.Array):
        """The layout of a new episode of a procedural tank: one of the tank set's tanks (params.tank), or a
        layout drawn by the generator (with structures when params.layout_structures > 0)."""
        if self.tanks is not None:
            i = jax.random.randint(key, (), 0, self.tanks.index.shape[0])
            return jax.tree.map(lambda x: x[i], self.tanks)
        if self.params.layout_structures > 0:
            return structures.draw(key, self.params)
        return layouts.draw(key, self.params)

    def _sample_point(self, key, water_fraction, avoid=None, min_distance=0.0, max_distance=np.inf, n=32,
                      layout=None):
        """A free point for a start or goal: in air or water, clear of obstacles and walls."""
        p = self.params
        obstacles, _, z_min = self.solids(layout)
        k_med, k_xy, k_z = jax.random.split(key, 3)
        water = jax.random.uniform(k_med) < water_fraction
        if self.procedural:  # the layout's region of the medium (layouts.default_regions, or narrower)
            region = jnp.where(water, layout.regions[1], layout.regions[0])
            xy = jax.random.uniform(k_xy, (n, 2), minval=region[0, :2], maxval=region[1, :2])
            lo, hi = region[0, 2], region[1, 2]
        else:
            lo, hi = jnp.where(water, jnp.asarray(p.water_band(z_min)), jnp.asarray(p.air_z_range))
            half = geometry.TANK_HALF_WIDTH - p.wall_margin
            xy = jax.random.uniform(k_xy, (n, 2), minval=-half, maxval=half)
        z = jax.random.uniform(k_z, (n, 1), minval=lo, maxval=hi)
        cand = jnp.concatenate([xy, z], -1)
        ok = jax.vmap(lambda c: geometry.signed_distance(obstacles, c))(cand) >= p.goal_clearance
        if avoid is not None:
            gap = jnp.linalg.norm(cand - avoid, axis=-1)
            ok &= (gap >= min_distance) & (gap <= max_distance)
        # Fallback if no candidate is valid (vanishingly rare): a point known to be free, the tank's
        # centre column in the fixed scenarios, a point the layout kept clear in a procedural tank.
        if self.procedural:
            fallback = jnp.where(water, layout.clear[1], layout.clear[0])
        else:
            fallback = jnp.where(water, jnp.array([0.0, 0.0, -0.6]), jnp.array([0.0, 0.0, 2.5]))
        return jnp.where(jnp.any(ok), cand[jnp.argmax(ok)], fallback)

    def sample_goal(self, key, position, layout=None):
        """A goal point (3,) for an episode starting at `position`: in water with `goal_water_fraction`,
        between `min_goal_distance` and `max_goal_distance` away, clear of the layout's solids (in its
        regions for a procedural tank)."""
        p = self.params
        return self._sample_point(key, p.goal_water_fraction, position, p.min_goal_distance, p.max_goal_distance,
                                  layout=layout)

    # ------------------------------------------------------------------ reset
    def reset(self, key: jax.Array, layout=None, plant=None) -> EnvState:
        """Random start (air or water), random yaw, random goal; level, at rest. A procedural tank
        draws its layout from `key` (`draw_layout`) unless `layout` is given (e.g. `layouts.held_out(i,
        params)`, a tank of `tanks.load_set`); starts and goals lie in the layout's regions;
        the plant is drawn from the `dr_*` ranges unless `plant` is given."""
        k_start, k_yaw, k_goal, k_rest = jax.random.split(key, 4)
        if self.procedural and layout is None:
            layout = self.draw_layout(jax.random.fold_in(key, 1))
        start = self._sample_point(k_start, self.params.start_water_fraction, layout=layout)
        yaw = jax.random.uniform(k_yaw, minval=-jnp.pi, maxval=jnp.pi)
        return self.reset_to(k_rest, start, yaw, self.sample_goal(k_goal, start, layout), layout=layout, plant=plant)

    def reset_to(self, key: jax.Array, position, yaw, goal, layout=None, plant=None) -> EnvState:
        """Vehicle at `position` with `yaw`, level and at rest, hovering thrust, heading for `goal`. A
        procedural tank without `layout` draws one that keeps `position` and `goal` clear (its `index`
        names the layout it derives from: the obstacles removed for clearance differ). A given `plant`
        is used as is: its latencies act only up to the queues the `dr_*_latency` ranges allot."""
        p = self.params
        position = _one_env("reset_to", "position", jnp.asarray(position, jnp.float32), (3,))
        goal = _one_env("reset_to", "goal", jnp.asarray(goal, jnp.float32), (3,))
        yaw = _one_env("reset_to", "yaw", jnp.asarray(yaw, jnp.float32), ())
        k_wind, k_noise, k_next = jax.random.split(key, 3)
        if self.procedural and layout is None:
            if self.tanks is not None:   # a tank as it is
                layout = self.draw_layout(jax.random.fold_in(key, 1))
            else:   # random obstacles only, cleared from the start and goal
                index = layouts.draw(jax.random.fold_in(key, 1), p).index
                layout = layouts.generate(layouts.layout_key(index), p, clear=jnp.stack([position, goal]))
                layout = layout.replace(index=index)
        if plant is None:
            plant = randomization.sample_plant(jax.random.fold_in(key, 2), p)
        quat = jnp.array([jnp.cos(yaw / 2), 0.0, 0.0, jnp.sin(yaw / 2)])
        data = self._data0.replace(qpos=jnp.concatenate([position, quat]), qvel=jnp.zeros(6))
        # Wind starts from the OU process's stationary distribution (std sigma / sqrt(1 - (1-theta)^2)).
        wind_std = plant.wind_sigma / np.sqrt(max(1.0 - (1.0 - p.wind_theta) ** 2, 1e-6))
        wind = wind_std * jax.random.normal(k_wind, (2,)) if p.wind else jnp.zeros(2)
        rot = physics.quat_to_mat(quat)
        underwater = position[2] < 0.0
        _, ranges = self._sense(data, layout, plant, k_noise, position, rot, underwater)
        obs = self._observe(ranges, underwater, jnp.zeros(3), position, rot, goal)
        sim = SimState(data=data, thrust=physics.hover_thrust(p, self.vehicle, position[2]),
                       vel_integral=jnp.zeros(3), wind=wind, goal=goal, step=jnp.zeros((), jnp.int32),
                       key=k_next, plant=plant, layout=layout,
                       # Until the first action arrives the controller holds a hover, (-1, 0, 0).
                       actions=jnp.tile(jnp.array([-1.0, 0.0, 0.0]), (self._action_queue, 1)),
                       observations=jnp.tile(obs, (self._obs_queue, 1)),
                       training_margins=jnp.asarray(p.collision_margin > 0.0 or p.hull_margin > 0.0))
        false = jnp.zeros((), bool)
        info = self._info(ranges, position, jnp.zeros(3), rot, goal, underwater, false, false, false, false,
                          false, sim.step, jnp.zeros((), jnp.int32), jnp.zeros((), jnp.int32))
        return EnvState(sim=sim, obs=obs, reward=jnp.zeros(()), done=false, info=info)

    # ------------------------------------------------------------------ step
    def step(self, state: EnvState, action: jax.Array) -> EnvState:
        """One control step: `action` (3,) in [-1, 1] (non-finite entries count as 0) commands the
        velocity controller over the physics substeps, then the active fan is cast and the reward and
        termination computed. Pure; after `done` the caller resets (AutoResetWrapper does it inside `step`)."""
        p, veh, sim = self.params, self.vehicle, state.sim
        key, k_wind, k_noise, k_goal = jax.random.split(sim.key, 4)

        # 1. Action: non-finite entries count as zero (and are counted), then clip to [-1, 1].
        action = _one_env("step", "action", jnp.asarray(action, jnp.float32), (ACTION_SIZE,), "(ACTION_SIZE,)")
        finite = jnp.isfinite(action)
        action = jnp.clip(jnp.where(finite, action, 0.0), -1.0, 1.0)
        # Action latency: the controller acts on the action of `plant.action_latency` steps ago.
        queue = jnp.concatenate([action[None], sim.actions])
        command = physics.command_from_action(p, queue[sim.plant.action_latency] if self._action_queue else action)

        # 2. Wind: OU update once per wind period (orig 2.6).
        wind = sim.wind
        if p.wind:
            updated = wind + p.wind_theta * (0.0 - wind) + sim.plant.wind_sigma * jax.random.normal(k_wind, (2,))
            wind = jnp.where(sim.step % self._wind_every == 0, updated, wind)

        # 3. Physics substeps.
        dt, plant = p.physics_dt, sim.plant

        def substep(carry, _):
            data, thrust, integral = carry
            pos, rot = data.qpos[:3], physics.quat_to_mat(data.qpos[3:7])
            vel, omega = data.qvel[:3], data.qvel[3:6]
            frac = physics.submerged_fraction(pos[2], p.hull_height)
            rotor_cmd, integral = physics.controller(p, veh, rot, vel, omega, frac, integral, command, dt)
            thrust = physics.rotor_response(plant, thrust, rotor_cmd, physics.rotor_limits(plant, pos, rot), dt)
            wrench = physics.medium_wrench(plant, veh, rot, vel, omega, thrust, wind, frac, dt)
            data = data.replace(xfrc_applied=data.xfrc_applied.at[self.body_id].set(wrench))
            return (mjx.step(self.mjx_model, data), thrust, integral), None

        prev_dist = jnp.linalg.norm(sim.goal - sim.data.qpos[:3])
        (data, thrust, integral), _ = jax.lax.scan(substep, (sim.data, sim.thrust, sim.vel_integral), None,
                                                   length=p.substeps, unroll=self.substep_unroll)

        # 4. Sensors, once per control step.
        position, rot = data.qpos[:3], physics.quat_to_mat(data.qpos[3:7])
        finite_state = jnp.all(jnp.isfinite(data.qpos)) & jnp.all(jnp.isfinite(data.qvel))
        position = jnp.where(finite_state, position, sim.data.qpos[:3])
        underwater = position[2] < 0.0
        true_ranges, ranges = self._sense(data, sim.layout, plant, k_noise, position, rot, underwater)

        # 5. Events and reward (collision on the noise-free geometry).
        obstacles, boundary, lo = self.solids(sim.layout)
        hi = p.bounds[1]
        # The hull's clearance to the obstacles serves the contact check and the training-only margin.
        to_obstacles = geometry.hull_clearance(obstacles, position, rot)
        touching = jnp.minimum(to_obstacles, geometry.hull_clearance(boundary, position, rot)) < 0.0
        margins = sim.training_margins
        collision = (jnp.min(true_ranges) < p.collision_distance + jnp.where(margins, p.collision_margin, 0.0)) | (
            touching | (margins & (to_obstacles < p.hull_margin)))
        out_of_bounds = (position[2] < lo) | (position[2] > hi)
        terminated = collision | out_of_bounds | ~finite_state
        dist = jnp.linalg.norm(sim.goal - position)
        arrived = (dist < p.arrival_distance) & ~terminated
        step = sim.step + 1
        truncated = (step >= p.max_episode_steps) & ~terminated
        reward = jnp.where(terminated, p.reward_collide,
                           jnp.where(arrived, p.reward_arrive, jnp.where(truncated, p.reward_timeout, 0.0)))
        if p.progress_reward_scale:
            reward = reward + p.progress_reward_scale * (prev_dist - dist)
        done = terminated | truncated
        if p.terminate_on_arrival:
            done = done | arrived
            goal = sim.goal
        else:
            goal = jnp.where(arrived, self.sample_goal(k_goal, position, sim.layout), sim.goal)

        obs = self._observe(ranges, underwater, action, position, rot, goal)
        # Observation latency: the agent sees the observation of `plant.obs_latency` steps ago.
        observations = jnp.concatenate([obs[None], sim.observations])
        if self._obs_queue:
            obs = observations[plant.obs_latency]
        goals_reached = state.info["goals_reached"] + arrived.astype(jnp.int32)
        bad_action = jnp.sum(~finite).astype(jnp.int32)
        info = self._info(ranges, position, data.qvel[:3], rot, goal, underwater, arrived, terminated,
                          truncated, collision, out_of_bounds, step, goals_reached, bad_action)
        # A diverged physics state (never seen; guarded anyway) ends the episode without NaNs leaking out.
        data = jax.tree.map(lambda new, old: jnp.where(finite_state, new, old), data, sim.data)
        sim = sim.replace(data=data, thrust=jnp.where(finite_state, thrust, sim.thrust),
                          vel_integral=jnp.where(finite_state, integral, sim.vel_integral), wind=wind, goal=goal,
                          step=step, key=key, actions=queue[:self._action_queue],
                          observations=observations[:self._obs_queue])
        return EnvState(sim=sim, obs=obs, reward=reward.astype(jnp.float32), done=done, info=info)

    # ------------------------------------------------------------------ rendering
    def render(self, states, camera: str = "both", width: int = 640, height: int = 240, **kwargs) -> np.ndarray:
        """Frames (T, H, W, 3) uint8 of one env's `states` (a sequence of EnvState, or one EnvState
        stacked over time) by MuJoCo's renderer: camera "follow", "overview" or "both" side by side;
        `fan=False` hides the range fan, `overlay=False` the text (docrl_jax/envs/rendering.py)."""
        from docrl_jax.envs import rendering
        return rendering.render_states(self, states, camera, width, height, **kwargs)

    # ------------------------------------------------------------------ helpers
    def _observe(self, ranges, underwater, action, position, rot, goal):
        scaled = ranges / sensors.max_range(self.params, underwater)
        obs = jnp.concatenate([scaled[:sensors.NUM_BEAMS], action, goal_features(position, physics.yaw_of(rot), goal),
                               scaled[sensors.NUM_BEAMS:]])
        return jnp.nan_to_num(obs).astype(jnp.float32)

    @staticmethod
    def _info(ranges, position, velocity, rot, goal, underwater, arrived, terminated, truncated, collision,
              out_of_bounds, step, goals_reached, nonfinite_action):
        # "ranges": the fan's; "vertical_ranges": every beam after it (`sensors.extra_directions`: up and
        # down with vertical_beams, then the slant_beams rings), empty (0,) without them; "rot": the body's
        # attitude (3, 3), body to world, as an IMU gives it (a map from the beams needs their directions)
        return {
            "ranges": ranges[:sensors.NUM_BEAMS], "vertical_ranges": ranges[sensors.NUM_BEAMS:],
            "position": position, "velocity": velocity, "yaw": physics.yaw_of(rot), "rot": rot,
            "goal": goal, "distance": jnp.linalg.norm(goal - position), "underwater": underwater,
            "arrived": arrived, "terminated": terminated, "truncated": truncated, "collision": collision,
            "out_of_bounds": out_of_bounds, "step": step, "goals_reached": goals_reached,
            "nonfinite_action": nonfinite_action,
        }
