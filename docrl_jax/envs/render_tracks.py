"""What the renderer (docrl_jax.envs.rendering) draws of one trajectory: a `Track` of poses and what
the env knew at each step, built from the env's states (`track_from_states`: `HUAUVEnv.render`, the
videos) or from the info dicts of its steps (`track_from_infos`: the Gymnasium adapter), and the text
over each frame (`overlay_lines`). Plain NumPy data: none of it needs MuJoCo or an OpenGL context."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

__all__ = ["CAMERAS", "Track", "overlay_lines", "track_from_infos", "track_from_states"]

# The renderer's views (docrl_jax.envs.rendering.Renderer's `camera`): here, so that a command line offers
# them without importing MuJoCo.
CAMERAS = ("both", "follow", "overview")


@dataclass
class Track:
    """What is drawn of one trajectory, per frame (leading axis T): the pose and what the env knew."""
    qpos: np.ndarray                      # (T, 7) position and quaternion (w, x, y, z)
    goal: np.ndarray                      # (T, 3)
    ranges: np.ndarray | None = None      # (T, 20) the ranges read (noise included); None: no fan
    vertical_ranges: np.ndarray | None = None  # (T, k) the beams after the fan (sensors.extra_directions);
    #                                            None or (T, 0): none
    underwater: np.ndarray | None = None  # (T,) bool: the sensor used (sonar when true)
    step: np.ndarray | None = None        # (T,) control steps since the start
    distance: np.ndarray | None = None    # (T,) metres to the goal
    status: Sequence[str] | None = None   # (T,) outcome text ("" while the trial goes on)
    title: str = ""                       # first overlay line, e.g. the method and the trial

    def __len__(self) -> int:
        return len(self.qpos)


def overlay_lines(track: Track, t: int) -> list[str]:
    """The text over frame `t` of `track`: its title, then step, medium and distance to the goal,
    then the outcome once there is one."""
    lines = [track.title] if track.title else []
    parts = []
    if track.step is not None:
        parts.append(f"step {int(track.step[t])}")
    wet = bool(track.underwater[t]) if track.underwater is not None else bool(track.qpos[t, 2] < 0)
    parts.append("water (sonar)" if wet else "air (LIDAR)")
    if track.distance is not None:
        parts.append(f"goal {float(track.distance[t]):.2f} m")
    lines.append("  ".join(parts))
    if track.status is not None and track.status[t]:
        lines.append(str(track.status[t]))
    return lines


def _status_of(info: dict[str, np.ndarray], t: int) -> str:
    for key, text in (("arrived", "arrived"), ("collision", "collision"), ("out_of_bounds", "out of bounds"),
                      ("truncated", "time-out")):
        if key in info and bool(info[key][t]):
            return text
    return ""


def track_from_infos(qpos: Sequence, infos: Sequence[dict]) -> Track:
    """A Track of poses (T, 7) and the env's info dicts (numpy) of the same steps (the Gymnasium
    adapter keeps these)."""
    info = {k: np.stack([np.asarray(i[k]) for i in infos]) for k in infos[0]}
    return Track(qpos=np.asarray(qpos, np.float64).reshape(-1, 7), goal=info["goal"], ranges=info["ranges"],
                 vertical_ranges=info.get("vertical_ranges"),
                 underwater=info["underwater"], step=info["step"], distance=info["distance"],
                 status=[_status_of(info, t) for t in range(len(infos))])


def track_from_states(states: Any) -> Track:
    """A Track of EnvStates: a sequence of single states or one state stacked over time."""
    import jax
    if isinstance(states, (list, tuple)):
        if not states:
            raise ValueError("render: no states given")
        states = jax.tree.map(lambda *xs: np.stack([np.asarray(x) for x in xs]), *states)
    sim, info = jax.device_get(states.sim), jax.device_get(states.info)
    qpos = np.asarray(sim.data.qpos)
    if qpos.ndim == 1:
        qpos, sim, info = qpos[None], jax.tree.map(lambda x: np.asarray(x)[None], sim), \
            jax.tree.map(lambda x: np.asarray(x)[None], info)
    if qpos.ndim != 2 or qpos.shape[1] != 7:
        raise ValueError(f"render: states of qpos shape {qpos.shape}: expected one env's states over time "
                         f"(T, 7); for a batch of envs, render one env at a time")
    return Track(qpos=qpos, goal=np.asarray(sim.goal), ranges=np.asarray(info["ranges"]),
                 vertical_ranges=np.asarray(info["vertical_ranges"]),
                 underwater=np.asarray(info["underwater"]), step=np.asarray(info["step"]),
                 distance=np.asarray(info["distance"]), status=[_status_of(info, t) for t in range(len(qpos))])


def frame_steps(n: int, every: int, last: bool = True) -> list[int]:
    """The entries of an n-entry track a video draws: every `every`-th, and the last when `last`."""
    idx = list(range(0, n, max(1, int(every))))
    return idx + [n - 1] if last and idx[-1] != n - 1 else idx
