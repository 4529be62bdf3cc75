"""An exported docrl_jax policy driven the way a ROS 2 node's timer callback would drive it, without ROS
and without docrl_jax: every control period (0.2 s, from policy.json) the callback reads the range fan
and the pose, builds the 26 observation floats exactly as the simulator did, steps the policy with
its carry and sends the action as velocity references. The carry is zeroed at every episode start.

The vehicle and its sensors are faked: a point vehicle that follows the commanded velocities exactly,
level, in the empty 9.8 x 9.8 m tank of scenario 1, flying the paper's air-to-water pair and back.
On a vehicle, FakeVehicle.ranges/pose are your sensor and odometry subscriptions and
FakeVehicle.command your velocity publisher.

    python -m docrl_jax.export --run tests/data/trained/td3_lstm --out /tmp/td3_export
    python examples/deploy_node.py --export /tmp/td3_export --artefact numpy --steps 600
    python examples/deploy_node.py --export /tmp/td3_export --artefact onnx --realtime   # at 5 Hz, Ctrl-C ends
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np


def load_policy(export_dir: Path, artefact: str):
    """(initial_carry, step) for one artefact; step(observation (1, 26), carry) -> (action (1, 3), carry)."""
    manifest = json.loads((export_dir / "policy.json").read_text())
    names = manifest["carry"]["names"]                      # ["c", "h"] for an LSTM with memory, else []
    units = manifest["policy"]["units"]

    def initial_carry():
        return tuple(np.zeros((1, units), np.float32) for _ in names)

    if artefact == "numpy":
        sys.path.insert(0, str(export_dir))
        from numpy_policy import NumpyPolicy                 # the loader copied beside the weights
        policy = NumpyPolicy(export_dir / manifest["files"]["numpy"]["weights"])
        return initial_carry, lambda obs, carry: policy.step(obs, carry)
    if artefact == "onnx":
        import onnxruntime as ort
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        session = ort.InferenceSession(str(export_dir / manifest["files"]["onnx"]["file"]), options,
                                       providers=["CPUExecutionProvider"])

        def step(obs, carry):
            action, *carry = session.run(None, dict(zip(["observation", *names], [obs, *carry])))
            return action, tuple(carry)
        return initial_carry, step
    if artefact == "stablehlo":
        import jax
        exported = jax.export.deserialize(bytearray((export_dir / manifest["files"]["stablehlo"]["file"]).read_bytes()))
        call = jax.jit(exported.call)

        def step(obs, carry):
            out = call(obs, *carry)
            out = out if names else (out,)
            return np.asarray(out[0]), tuple(np.asarray(x) for x in out[1:])
        return initial_carry, step
    raise SystemExit(f"--artefact {artefact!r}: valid artefacts are numpy, onnx, stablehlo")


def build_observation(manifest: dict, ranges_m, underwater: bool, previous_action, position, yaw: float, goal):
    """The observation floats (policy.json "observation"): ranges over the active sensor's maximum, the
    previous action, then the goal's bearing / pi, elevation / (pi / 2) and distance / scale: 26. A
    policy trained with vertical or slanted beams ("vertical_ranges", "slanted_ranges" entries) takes
    their ranges after the fan's, in the manifest's order, and gets them at the end."""
    layout = {entry["name"]: entry for entry in manifest["observation"]["layout"]}
    beams, goal_distance = layout["ranges"], layout["goal_distance"]
    num_beams = beams["index"][1] + 1
    num_ranges = num_beams + sum(layout[name]["index"][1] - layout[name]["index"][0] + 1
                                 for name in ("vertical_ranges", "slanted_ranges") if name in layout)
    if len(ranges_m) != num_ranges:
        raise ValueError(f"{len(ranges_m)} ranges given; this policy takes {num_ranges} (policy.json observation)")
    max_range = beams["sonar" if underwater else "lidar"]["max_range_m"]
    scaled = np.asarray(ranges_m, np.float32) / np.float32(max_range)
    fan, vertical = scaled[:num_beams], scaled[num_beams:]
    dx, dy, dz = np.asarray(goal, np.float64) - np.asarray(position, np.float64)
    bearing = math.atan2(dy, dx) - yaw
    bearing = math.atan2(math.sin(bearing), math.cos(bearing))                 # wrapped to [-pi, pi]
    elevation = math.atan2(dz, math.hypot(dx, dy))
    distance = min(math.sqrt(dx * dx + dy * dy + dz * dz) / goal_distance["scale_m"], 1.0)
    obs = np.concatenate([fan, np.asarray(previous_action, np.float32),
                          np.array([bearing / math.pi, elevation / (math.pi / 2), distance], np.float32), vertical])
    return np.nan_to_num(obs).astype(np.float32)


class FakeVehicle:
    """Sensors and actuators of a point vehicle in the empty tank (walls at x, y = +-4.9 m, floor top at
    z = -1.3 m, no ceiling)."""
    WALL, FLOOR = 4.9, -1.3

    def __init__(self, manifest: dict, position, yaw: float = 0.0):
        self.position, self.yaw = np.array(position, np.float64), yaw
        self.speeds = [entry["max_m_s" if "max_m_s" in entry else "max"] for entry in manifest["action"]["layout"]]
        layout = {entry["name"]: entry for entry in manifest["observation"]["layout"]}
        self.fans, self.vertical = layout["ranges"], "vertical_ranges" in layout
        if "slanted_ranges" in layout:   # rings of beams against walls and floor: not worth a demo's geometry
            raise ValueError("this fake vehicle casts the fans and the vertical beams only, not slanted beams")
        self.num_beams = self.fans["index"][1] + 1

    def ranges(self):
        """(ranges in metres, underwater): the active fan, level, cast against the four walls; then, for a
        policy with vertical beams, up (nothing: the maximum) and down (the floor, through the water)."""
        underwater = self.position[2] < 0.0                   # the sonar below the surface, as in training
        fan = self.fans["sonar" if underwater else "lidar"]
        angles = self.yaw + np.deg2rad(fan["bearings_deg"])
        d = np.stack([np.cos(angles), np.sin(angles)], -1)
        with np.errstate(divide="ignore"):
            t = np.where(d > 0, (self.WALL - self.position[:2]) / d, (-self.WALL - self.position[:2]) / d)
        ranges = np.minimum(np.min(np.where(np.abs(d) > 1e-9, t, np.inf), axis=-1), fan["max_range_m"])
        if self.vertical:
            ranges = np.append(ranges, [fan["max_range_m"], min(self.position[2] - self.FLOOR, fan["max_range_m"])])
        return ranges, underwater

    def command(self, action, dt: float):
        """Follows the velocity references of `action` for dt seconds (policy.json "action")."""
        max_v, max_vz, max_dpsi = self.speeds
        v, vz, dpsi = (action[0] + 1.0) / 2.0 * max_v, action[1] * max_vz, action[2] * max_dpsi
        heading = self.yaw + dpsi
        self.position += dt * np.array([v * math.cos(heading), v * math.sin(heading), vz])
        self.yaw += dpsi * dt


class PolicyNode:
    """What a ROS 2 node would hold: the policy, its carry, the last action; `on_timer` is the callback."""
    PAIRS = [((0.0, 0.0, 2.5), (2.0, 3.0, -1.0)), ((2.0, 3.0, -1.0), (0.0, 0.0, 2.5))]   # scenario 1, A-W and W-A

    def __init__(self, export_dir: Path, artefact: str, max_episode_steps: int = 500):
        self.manifest = json.loads((export_dir / "policy.json").read_text())
        self.initial_carry, self.step = load_policy(export_dir, artefact)
        self.period = self.manifest["control_period_s"]
        self.max_episode_steps, self.episode, self.log = max_episode_steps, -1, []
        self.start_episode()

    def start_episode(self):
        self.episode += 1
        start, self.goal = self.PAIRS[self.episode % 2]
        self.vehicle = FakeVehicle(self.manifest, start)
        self.carry = self.initial_carry()                     # the carry is zeroed at every episode start
        self.previous_action = np.zeros(3, np.float32)
        self.steps = 0

    def on_timer(self):
        ranges, underwater = self.vehicle.ranges()
        obs = build_observation(self.manifest, ranges, underwater, self.previous_action, self.vehicle.position,
                                self.vehicle.yaw, self.goal)
        action, self.carry = self.step(obs[None], self.carry)
        action = np.clip(np.nan_to_num(action[0]), -1.0, 1.0).astype(np.float32)
        self.vehicle.command(action, self.period)             # publish the velocity references
        self.previous_action, self.steps = action, self.steps + 1
        distance = float(np.linalg.norm(np.asarray(self.goal) - self.vehicle.position))
        fan = self.vehicle.ranges()[0][:self.vehicle.num_beams]   # the collision check reads the fan only
        crashed = min(fan) < 0.5 or not -1.1 < self.vehicle.position[2] < 4.8
        end = "arrived" if distance < 0.5 else "crashed" if crashed else (
            "timed out" if self.steps >= self.max_episode_steps else None)
        if end:
            self.log.append((self.episode, end, self.steps))
            print(f"episode {self.episode} ({'A-W' if self.episode % 2 == 0 else 'W-A'}): {end} after {self.steps} "
                  f"steps ({self.steps * self.period:.1f} s)", flush=True)
            self.start_episode()
        return action


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--export", type=Path, required=True, help="a directory written by python -m docrl_jax.export")
    p.add_argument("--artefact", default="numpy", choices=["numpy", "onnx", "stablehlo"])
    p.add_argument("--steps", type=int, default=600, help="timer callbacks to run (default 600 = 2 min of flight)")
    p.add_argument("--realtime", action="store_true", help="call back every control period, as a 5 Hz timer would")
    args = p.parse_args(argv)
    node = PolicyNode(args.export, args.artefact)
    busy, next_tick = [], time.monotonic()
    for _ in range(args.steps):
        t0 = time.perf_counter()
        node.on_timer()
        busy.append(time.perf_counter() - t0)
        if args.realtime:
            next_tick += node.period
            time.sleep(max(0.0, next_tick - time.monotonic()))
    print(f"{args.steps} callbacks with the {args.artefact} artefact: median {np.median(busy) * 1e6:.0f} us each "
          f"(sensors, observation, policy), control period {node.period * 1e3:.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
