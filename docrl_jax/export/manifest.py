"""`policy.json`, the manifest of an export: what the exported step function takes and returns, in
the units a vehicle's software has to produce and consume, read from the run's own environment
parameters (its beams, ranges, speeds and control period), and where the policy came from.

Everything a deployment needs to build the observation (26 floats, more with vertical or slanted
beams) is here: which float is which beam, the normalisations, the goal vector's definitions; then
the action's meaning, the carry and its reset.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import numpy as np

from docrl_jax import resources
from docrl_jax.config import Config, env_kwargs
from docrl_jax.envs import make_params
from docrl_jax.envs.params import VERTICAL_BEAMS

FORMAT = "docrl_jax policy export, version 1"
VERSION_PACKAGES = ("docrl_jax", "jax", "jaxlib", "flax", "numpy", "jax2onnx", "onnx", "onnxruntime")
BATCH = "B"   # the symbolic batch dimension of the ONNX and StableHLO artefacts (1 for one vehicle)


def versions() -> dict[str, str | None]:
    """Installed versions of the packages that made (or can run) the artefacts; None = not installed."""
    return resources.versions(VERSION_PACKAGES)


def io_names(recurrent: bool) -> tuple[list[str], list[str]]:
    """Input and output names of the step function (ONNX names them so; the others take them in order)."""
    if recurrent:
        return ["observation", "c", "h"], ["action", "c_out", "h_out"]
    return ["observation"], ["action"]


def _beams(fov_deg: float, max_range: float) -> dict[str, Any]:
    from docrl_jax.envs.sensors import beam_angles   # (the env's modules import JAX: `export --help` need not)
    return {"fov_deg": fov_deg, "max_range_m": max_range,
            "bearings_deg": [round(float(a), 4) for a in np.rad2deg(beam_angles(fov_deg))]}


def observation_spec(config: Config) -> dict[str, Any]:
    from docrl_jax.envs import ACTION_SIZE, DIST_SCALE, OBS_SIZE
    from docrl_jax.envs.sensors import NUM_BEAMS
    p = make_params(config.env.scenario, **env_kwargs(config))
    vertical = [{"index": [OBS_SIZE, OBS_SIZE + VERTICAL_BEAMS - 1], "name": "vertical_ranges",
                 "value": "range / max range of the active sensor, in [0, 1], of two beams from the vehicle centre "
                          "along body +z (up), then body -z (down); like the fans they see walls, floor and "
                          "obstacles, not the water surface"}] if p.vertical_beams else []
    first = OBS_SIZE + VERTICAL_BEAMS * p.vertical_beams
    slanted = [{"index": [first, p.observation_size - 1], "name": "slanted_ranges",
                "value": f"range / max range of the active sensor, in [0, 1], of two rings of {p.slant_beams} beams "
                         f"from the vehicle centre, {p.slant_elevation_deg:g} degrees above (the first ring), then "
                         "below the body x-y plane, at bearings k * 360 / n degrees from body x, counter-clockwise "
                         "positive; like the fans they see walls, floor and obstacles, not the water surface"}
               ] if p.slant_beams else []
    return {
        "size": p.observation_size, "dtype": "float32", "shape": [BATCH, p.observation_size],
        "frame": "world frame, z up, water surface at z = 0; (dx, dy, dz) = goal - vehicle centre (m); yaw = "
                 "heading of the body x axis about world z (rad)",
        "layout": [
            {"index": [0, NUM_BEAMS - 1], "name": "ranges",
             "value": "range / max range of the active sensor, in [0, 1]; a beam without a return reads 1",
             "beams": f"beam k (0..{NUM_BEAMS - 1}) leaves the vehicle centre in the body x-y plane (it tilts with "
                      "the body) at bearing bearings_deg[k] from body x (forward), counter-clockwise positive "
                      "(towards body +y, the left); evenly spaced over the fan, both ends included",
             "active_sensor": "sonar while the vehicle centre is below the water surface (z < 0), else LIDAR; "
                              "only one fan is in the observation at a time",
             "lidar": _beams(p.lidar_fov_deg, p.lidar_max_range),
             "sonar": _beams(p.sonar_fov_deg, p.sonar_max_range),
             "training_noise_std_m": p.sensor_noise_std},
            {"index": [NUM_BEAMS, NUM_BEAMS + ACTION_SIZE - 1], "name": "previous_action",
             "value": "the action applied over the last control period (the policy's previous output, clipped to "
                      "[-1, 1], non-finite entries as 0); zeros on an episode's first step"},
            {"index": NUM_BEAMS + ACTION_SIZE, "name": "goal_bearing",
             "value": "wrap_to_pi(atan2(dy, dx) - yaw) / pi, in [-1, 1]; positive: the goal is to the left"},
            {"index": NUM_BEAMS + ACTION_SIZE + 1, "name": "goal_elevation",
             "value": "atan2(dz, hypot(dx, dy)) / (pi / 2), in [-1, 1]; positive: the goal is above"},
            {"index": NUM_BEAMS + ACTION_SIZE + 2, "name": "goal_distance", "scale_m": DIST_SCALE,
             "value": f"min(sqrt(dx^2 + dy^2 + dz^2) / {DIST_SCALE:.4f} m, 1) (the training tank's inner diagonal)"},
            *vertical,
            *slanted,
        ],
        "non_finite": "the simulator's observation replaces NaN by 0; give the policy finite values",
    }


def action_spec(config: Config) -> dict[str, Any]:
    from docrl_jax.envs import ACTION_SIZE
    p = make_params(config.env.scenario, **env_kwargs(config))
    return {
        "size": ACTION_SIZE, "dtype": "float32", "shape": [BATCH, ACTION_SIZE], "range": [-1.0, 1.0],
        "layout": [
            {"index": 0, "name": "forward_speed", "max_m_s": p.max_forward_speed,
             "value": f"v = (a0 + 1) / 2 * {p.max_forward_speed} m/s, horizontal, along heading yaw + dpsi"},
            {"index": 1, "name": "vertical_speed", "max_m_s": p.max_vertical_speed,
             "value": f"vz = a1 * {p.max_vertical_speed} m/s (world z, up positive)"},
            {"index": 2, "name": "heading_change", "max": p.max_yaw_change,
             "value": f"dpsi = a2 * {p.max_yaw_change}: the horizontal velocity's heading offset from yaw (rad) and "
                      "the yaw-rate reference (rad/s)"},
        ],
        "use": "velocity references for the vehicle's own velocity controller, held for one control period; "
               "(-1, 0, 0) hovers; the simulator clipped actions to [-1, 1]",
    }


def carry_spec(config: Config) -> dict[str, Any]:
    if not config.agent.recurrent:
        why = "an MLP actor" if config.agent.actor == "mlp" else "an LSTM trained without memory (agent.memory false)"
        return {"names": [], "note": f"none: {why} acts on the current observation alone"}
    units = config.agent.actor_hidden[0]
    return {"names": ["c", "h"], "outputs": ["c_out", "h_out"], "shape": [BATCH, units], "dtype": "float32",
            "initial_value": 0.0,
            "reset": "zeros at every episode start (a new goal after arrival does not reset it; a new start does)",
            "order": "Flax's LSTM carry (c, h): c the cell state, h the hidden state; feed c_out, h_out back as "
                     "c, h on the next step"}


def policy_spec(config: Config) -> dict[str, Any]:
    a = config.agent
    head = "tanh(mean Dense(h)), SAC's deterministic action (log_std unused)" if a.algo == "sac" else "tanh(Dense(h))"
    body = (f"OptimizedLSTMCell({a.actor_hidden[0]}) (Flax)" if a.actor == "lstm"
            else " -> ".join(f"relu(Dense({w}))" for w in a.actor_hidden))
    return {"config": config.name, "algo": a.algo, "actor": a.actor, "hidden": list(a.actor_hidden),
            "units": a.actor_hidden[0] if a.actor == "lstm" else None, "recurrent": a.recurrent,
            "network": f"observation -> {body} -> {head}"}


def build(config: Config, source: dict[str, Any], files: dict[str, Any], check: dict[str, Any]) -> dict[str, Any]:
    p = make_params(config.env.scenario, **env_kwargs(config))
    inputs, outputs = io_names(config.agent.recurrent)
    return {
        "format": FORMAT,
        "policy": policy_spec(config),
        "step_function": f"({', '.join(inputs)}) -> ({', '.join(outputs)}), once per control period",
        "control_period_s": p.control_dt,
        "observation": observation_spec(config),
        "action": action_spec(config),
        "carry": carry_spec(config),
        "source": source,
        "files": files,
        "check": check,
        "versions": versions(),
        "created_utc": dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds"),
    }
