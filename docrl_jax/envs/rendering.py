"""MuJoCo's own renderer (`mujoco.Renderer`) for HUAUV scenes: what `HUAUVEnv.render`, the Gymnasium
adapter's `render_mode="rgb_array"`, `python -m docrl_jax.render` and the trainer's TensorBoard videos draw.

Two views, side by side (`camera="both"`) or one alone: `follow`, a camera behind the vehicle that
turns with it (pulled in when a wall or an obstacle is between it and the vehicle), and `overview`,
the whole tank from above one corner, with the walls nearest to it see-through. On top of the scene:
the water as a translucent blue-green volume with its surface line drawn on the walls, a blue-green
tint and fog over a view whose camera is under water, the goal (a translucent sphere of the arrival
radius), the active range fan (LIDAR in air, sonar under water; `sensors.beam_directions`) and the
vertical and slanted beams (`vertical_beams`, `slant_beams`) with their hits, the path so far, rotor
discs that show the vehicle's heading (red at the front), and a text overlay (step, medium, distance
to the goal, outcome; Pillow's ImageDraw).

Render-only: the decorations are extra geoms put into the renderer's scene after `update_scene`
(`mjv_initGeom`, `mjv_connector`), and the lights, fog and buffer size are set on a copy of the
env's MjModel; the MJCF that the physics and MJX's rays use is never changed.

The OpenGL backend is chosen by MuJoCo when `mujoco` is first imported, from MUJOCO_GL;
`docrl_jax/__init__.py` sets egl (or osmesa) on a Linux machine with no display when it is unset.
When no context can be created, `Renderer` raises `RenderError` naming MUJOCO_GL and its values.

What a frame shows of a trajectory (a `Track`, built from env states or Gymnasium infos) and the
text over it come from docrl_jax.envs.render_tracks.
"""

from __future__ import annotations

import copy
import warnings
from typing import Any, Sequence

import mujoco
import numpy as np

from docrl_jax.envs import sensors
from docrl_jax.envs.geometry import TANK_HALF_WIDTH
from docrl_jax.envs.params import EnvParams
from docrl_jax.envs.render_tracks import (CAMERAS, Track, frame_steps, overlay_lines, track_from_infos,
                                          track_from_states)
from docrl_jax.errors import RenderError, short_reason

# What is drawn of a trajectory (`Track`) and its builders live in docrl_jax.envs.render_tracks; they
# are named here too, beside the renderer that draws them.
__all__ = ["CAMERAS", "RenderError", "Renderer", "Track", "make_gl_renderer", "render_states", "scene_model",
           "track_from_infos", "track_from_states"]


WATER_RGBA = (0.05, 0.55, 0.6, 0.22)         # the water volume seen from above
SURFACE_RGBA = (0.3, 0.95, 1.0, 1.0)         # the surface line on the walls
TINT_RGB = np.array([20.0, 95.0, 105.0])     # blended over a view whose camera is under water
TINT = 0.35
GOAL_RGBA = (0.2, 0.95, 0.3, 0.35)
LIDAR_RGBA = (1.0, 0.85, 0.1, 0.9)
SONAR_RGBA = (1.0, 0.3, 0.85, 0.9)
TRAIL_RGBA = (1.0, 1.0, 1.0, 0.8)
FOLLOW = {"distance": 2.2, "elevation": -12.0}
OVERVIEW = {"lookat": (0.0, 0.0, 0.2), "distance": 16.5, "azimuth": 120.0, "elevation": -42.0}
_SOLIDS = np.array([0, 1, 0, 0, 0, 0], np.uint8)   # what the follow camera must not go through (group 1)


def make_gl_renderer(model: mujoco.MjModel, height: int, width: int) -> mujoco.Renderer:
    """`mujoco.Renderer`, or RenderError naming MUJOCO_GL when no OpenGL context can be created (no
    library, no display for GLFW, a broken driver: the same to a user). GLFW explains itself in
    warnings, which then go into the error's one line."""
    error = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            renderer = mujoco.Renderer(model, height, width)
        except Exception as e:
            error = e
    if error is not None:
        said = [str(w.message).strip() for w in caught][:1]
        raise RenderError.no_gl("; ".join(said + [short_reason(error, 120)])) from None
    for w in caught:   # a context that started: its warnings as usual
        warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    return renderer


def _quat_mat(q) -> np.ndarray:
    mat = np.zeros(9)
    mujoco.mju_quat2Mat(mat, np.asarray(q, np.float64))
    return mat.reshape(3, 3)


class Renderer:
    """A reusable renderer for one scene and frame size; `close()` it (or use `with`): MuJoCo's GL
    context otherwise reports errors when the interpreter exits.

    `width` x `height` is the whole frame; with camera "both" each view is width // 2 wide.
    `antialias=False` (no multisampling) draws about twice as fast on a CPU (Mesa's llvmpipe), with
    jagged lines; the shadow map is 1024 pixels (MuJoCo's 4096 costs a third of the speed there)."""

    def __init__(self, mj_model: mujoco.MjModel, params: EnvParams, width: int = 640, height: int = 240,
                 camera: str = "both", fan: bool = True, overlay: bool = True, trail: bool = True,
                 antialias: bool = True):
        if camera not in CAMERAS:
            raise ValueError(f"camera={camera!r}: valid cameras are {', '.join(CAMERAS)}")
        if width < 16 or height < 16:
            raise ValueError(f"frame {width}x{height}: width and height must be at least 16 pixels")
        self.params, self.camera, self.fan, self.overlay, self.trail = params, camera, fan, overlay, trail
        self.width, self.height = int(width), int(height)
        self.views = ("follow", "overview") if camera == "both" else (camera,)
        self.view_width = self.width // len(self.views)
        model = copy.copy(mj_model)   # only visual settings change, on this copy
        model.vis.global_.offwidth = max(model.vis.global_.offwidth, self.view_width)
        model.vis.global_.offheight = max(model.vis.global_.offheight, self.height)
        model.vis.quality.offsamples = 4 if antialias else 0
        model.vis.quality.shadowsize = 1024
        model.vis.headlight.ambient[:] = 0.35
        model.vis.headlight.diffuse[:] = 0.45
        model.vis.headlight.specular[:] = 0.1
        model.vis.rgba.fog[:] = (*(TINT_RGB / 255.0), 1.0)
        model.vis.map.fogstart, model.vis.map.fogend = 0.0, 14.0 / max(model.stat.extent, 1e-6)
        self.model = model
        self.data = mujoco.MjData(model)
        self.body_id = model.body("huauv").id
        self.rotor_sites = [model.site(f"rotor_{n}").id for n in ("front_left", "back_left", "back_right", "front_right")]
        floor = [i for i in range(model.ngeom) if model.geom(i).name == "floor"]
        self.floor_top = (float(model.geom_pos[floor[0], 2] + model.geom_size[floor[0], 2]) if floor
                          else float(params.bounds[0]))
        self.walls = {i: model.geom_pos[i, :2].copy() for i in range(model.ngeom)
                      if model.geom(i).name.startswith("wall_")}
        self.option = mujoco.MjvOption()
        for g in range(6):
            self.option.geomgroup[g] = 1
        self._cams = {v: mujoco.MjvCamera() for v in ("follow", "overview")}
        for cam in self._cams.values():
            cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        ov = self._cams["overview"]
        ov.lookat[:], ov.distance = OVERVIEW["lookat"], OVERVIEW["distance"]
        ov.azimuth, ov.elevation = OVERVIEW["azimuth"], OVERVIEW["elevation"]
        self._renderer = make_gl_renderer(model, self.height, self.view_width)
        self._font = None

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        if getattr(self, "_renderer", None) is not None:
            self._renderer.close()
            self._renderer = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ------------------------------------------------------------------ frames
    def render_track(self, track: Track, every: int = 1, last: bool = True) -> np.ndarray:
        """Frames (F, H, W, 3) uint8 of every `every`-th entry of `track` (and of its last when `last`)."""
        idx = frame_steps(len(track), every, last)
        cam_yaw = self._smooth_yaw(track.qpos)
        frames = np.empty((len(idx), self.height, self.width, 3), np.uint8)
        for k, t in enumerate(idx):
            frames[k] = self.track_frame(track, t, cam_yaw[t])
        return frames

    def track_frame(self, track: Track, t: int = -1, cam_yaw: float | None = None) -> np.ndarray:
        """The frame (H, W, 3) of entry `t` of `track`, its path so far drawn behind it; the follow
        camera's heading is the track's smoothed yaw unless `cam_yaw` is given."""
        t = t % len(track)
        if cam_yaw is None:
            cam_yaw = self._smooth_yaw(track.qpos[:t + 1])[-1]
        return self.frame(track.qpos[t], track.goal[t], None if track.ranges is None else track.ranges[t],
                          None if track.underwater is None else bool(track.underwater[t]),
                          lines=overlay_lines(track, t), trail=track.qpos[:t + 1, :3], cam_yaw=cam_yaw,
                          vertical_ranges=None if track.vertical_ranges is None else track.vertical_ranges[t])

    def frame(self, qpos, goal, ranges=None, underwater: bool | None = None, lines: Sequence[str] = (),
              trail=None, cam_yaw: float | None = None, vehicle: bool = True, vertical_ranges=None) -> np.ndarray:
        """One frame (H, W, 3) uint8 of the vehicle at `qpos` heading for `goal`. `ranges`: the active
        fan's ranges and `vertical_ranges` those of the beams after it, up and down, then slanted (both
        drawn when the renderer's `fan` is on); `underwater`: which fan (default: by the vehicle's depth);
        `trail`: past positions (k, 3); `cam_yaw`: the follow camera's heading in radians (default the
        vehicle's); `vehicle=False` leaves the vehicle out (tests find its pixels)."""
        qpos = np.asarray(qpos, np.float64)
        self.data.qpos[:] = qpos
        mujoco.mj_kinematics(self.model, self.data)
        rot = _quat_mat(qpos[3:7])
        if cam_yaw is None:
            cam_yaw = float(np.arctan2(rot[1, 0], rot[0, 0]))
        if underwater is None:
            underwater = bool(qpos[2] < 0.0)
        self.option.geomgroup[3] = int(vehicle)
        views = []
        for view in self.views:
            cam = self._cams[view]
            if view == "follow":
                self._aim_follow(cam, qpos[:3], cam_yaw)
            self._renderer.update_scene(self.data, cam, self.option)
            scene = self._renderer.scene
            cam_pos = self._camera_position(cam)
            wet = cam_pos[2] < 0.0
            scene.flags[mujoco.mjtRndFlag.mjRND_FOG] = wet
            self._decorate(scene, view, qpos, rot, np.asarray(goal, np.float64), ranges, vertical_ranges, underwater,
                           trail, vehicle, cam_pos)
            img = self._renderer.render().astype(np.float32)
            if wet:
                img = (1.0 - TINT) * img + TINT * TINT_RGB
            views.append(np.clip(img, 0, 255).astype(np.uint8))
        out = np.concatenate(views, axis=1) if len(views) > 1 else views[0]
        if out.shape[1] != self.width:   # an odd width with two views: one column of padding
            out = np.pad(out, ((0, 0), (0, self.width - out.shape[1]), (0, 0)))
        if self.overlay and lines:
            out = self._draw_text(out, lines)
        return out

    # ------------------------------------------------------------------ cameras
    def _aim_follow(self, cam, position, yaw: float) -> None:
        cam.lookat[:] = position
        cam.azimuth, cam.elevation = np.degrees(yaw), FOLLOW["elevation"]
        back = -self._forward(cam)
        hit = mujoco.mj_ray(self.model, self.data, position, back, _SOLIDS, 1, self.body_id, np.array([-1], np.int32))
        cam.distance = FOLLOW["distance"] if hit < 0 else float(np.clip(hit - 0.25, 0.3, FOLLOW["distance"]))

    @staticmethod
    def _forward(cam) -> np.ndarray:
        az, el = np.radians(cam.azimuth), np.radians(cam.elevation)
        return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])

    def _camera_position(self, cam) -> np.ndarray:
        return np.asarray(cam.lookat, np.float64) - cam.distance * self._forward(cam)

    @staticmethod
    def _smooth_yaw(qpos: np.ndarray, rate: float = 0.25) -> np.ndarray:
        """The follow camera's heading over a track: the vehicle's yaw, low-pass filtered (a camera
        that snaps with every yaw correction shakes)."""
        q = np.asarray(qpos)[:, 3:7]
        yaw = np.unwrap(np.arctan2(2 * (q[:, 0] * q[:, 3] + q[:, 1] * q[:, 2]), 1 - 2 * (q[:, 2] ** 2 + q[:, 3] ** 2)))
        out = np.empty_like(yaw)
        for t, y in enumerate(yaw):
            out[t] = y if t == 0 else out[t - 1] + rate * (y - out[t - 1])
        return out

    # ------------------------------------------------------------------ decorations
    def _add(self, scene, kind, size, pos, rgba, mat=None):
        if scene.ngeom >= scene.maxgeom:
            return None
        g = scene.geoms[scene.ngeom]
        mujoco.mjv_initGeom(g, kind, np.asarray(size, np.float64), np.asarray(pos, np.float64),
                            np.eye(3).ravel() if mat is None else np.asarray(mat, np.float64).ravel(),
                            np.asarray(rgba, np.float32))
        g.transparent = int(rgba[3] < 1.0)
        scene.ngeom += 1
        return g

    def _line(self, scene, a, b, rgba, width: float = 2.0):
        g = self._add(scene, mujoco.mjtGeom.mjGEOM_LINE, np.zeros(3), np.zeros(3), rgba)
        if g is not None:
            mujoco.mjv_connector(g, mujoco.mjtGeom.mjGEOM_LINE, width, np.asarray(a, np.float64),
                                 np.asarray(b, np.float64))

    def _decorate(self, scene, view, qpos, rot, goal, ranges, vertical_ranges, underwater, trail, vehicle,
                  cam_pos) -> None:
        if view == "overview":   # the walls between the camera and the tank are see-through
            for i in range(scene.ngeom):
                g = scene.geoms[i]
                if g.objtype == mujoco.mjtObj.mjOBJ_GEOM and g.objid in self.walls \
                        and float(np.dot(self.walls[g.objid], cam_pos[:2])) > 0:
                    g.rgba[3] = 0.12
                    g.transparent = 1
        depth = -self.floor_top
        t = TANK_HALF_WIDTH
        self._add(scene, mujoco.mjtGeom.mjGEOM_BOX, (t, t, depth / 2), (0, 0, -depth / 2), WATER_RGBA)
        corners = [(-t, -t), (t, -t), (t, t), (-t, t), (-t, -t)]
        for (x0, y0), (x1, y1) in zip(corners[:-1], corners[1:]):
            self._line(scene, (x0, y0, 0.0), (x1, y1, 0.0), SURFACE_RGBA, 3.0)
        r = self.params.arrival_distance
        self._add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, (r, r, r), goal, GOAL_RGBA)
        self._add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, (0.07,) * 3, goal, (0.2, 1.0, 0.3, 1.0))
        if self.trail and trail is not None and len(trail) > 1:
            pts = np.asarray(trail)[:: max(1, len(trail) // 150)]
            pts = np.concatenate([pts, np.asarray(trail)[-1:]])
            for a, b in zip(pts[:-1], pts[1:]):
                self._line(scene, a, b, TRAIL_RGBA, 2.0)
        if vehicle:
            for k, site in enumerate(self.rotor_sites):
                front = k in (0, 3)
                self._add(scene, mujoco.mjtGeom.mjGEOM_CYLINDER, (0.11, 0.012, 0.11), self.data.site_xpos[site],
                          (0.95, 0.15, 0.1, 1.0) if front else (0.95, 0.95, 0.95, 1.0), rot)
        if vehicle and view == "overview":   # the vehicle is a few pixels in the overview: a halo shows it
            self._add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, (0.4,) * 3, qpos[:3], (1.0, 0.25, 0.2, 0.55))
        if self.fan and ranges is not None:
            ranges = np.asarray(ranges, np.float64)
            fov = self.params.sonar_fov_deg if underwater else self.params.lidar_fov_deg
            angles = sensors.beam_angles(fov)   # the env's beams (sensors.beam_directions), in NumPy
            dirs = np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], -1) @ rot.T
            if vertical_ranges is not None and len(vertical_ranges):
                ranges = np.concatenate([ranges, np.asarray(vertical_ranges, np.float64)])
                extra = sensors.extra_directions(self.params)
                if len(extra) != len(vertical_ranges):
                    raise ValueError(f"{len(vertical_ranges)} ranges after the fan, but the renderer's params have "
                                     f"{len(extra)} such beams (vertical_beams, slant_beams): render with the "
                                     "params of the env that recorded them")
                dirs = np.concatenate([dirs, extra @ rot.T])
            limit = self.params.sonar_max_range if underwater else self.params.lidar_max_range
            rgba = SONAR_RGBA if underwater else LIDAR_RGBA
            for d, rng in zip(dirs, ranges):
                end = qpos[:3] + rng * d
                self._line(scene, qpos[:3], end, rgba, 1.5)
                if rng < limit - 1e-3:
                    self._add(scene, mujoco.mjtGeom.mjGEOM_SPHERE, (0.06,) * 3, end, (*rgba[:3], 1.0))

    # ------------------------------------------------------------------ text
    def _draw_text(self, frame: np.ndarray, lines: Sequence[str]) -> np.ndarray:
        from PIL import Image, ImageDraw, ImageFont
        if self._font is None:
            size = max(9, self.height // 20)
            try:
                self._font = ImageFont.load_default(size=size)
            except TypeError:   # Pillow < 10.1: the fixed bitmap font
                self._font = ImageFont.load_default()
        img = Image.fromarray(frame)
        draw = ImageDraw.Draw(img, "RGBA")
        pad = 3
        boxes = [draw.textbbox((0, 0), line, font=self._font) for line in lines]
        step = max(b[3] - b[1] for b in boxes) + 2
        width = max(b[2] - b[0] for b in boxes)
        draw.rectangle((0, 0, width + 2 * pad, step * len(lines) + 2 * pad), fill=(0, 0, 0, 140))
        for k, line in enumerate(lines):
            draw.text((pad, pad + k * step), line, fill=(255, 255, 255, 255), font=self._font)
        return np.asarray(img)


# ------------------------------------------------------------------ from env states
def render_states(env, states: Any, camera: str = "both", width: int = 640, height: int = 240,
                  fan: bool = True, overlay: bool = True) -> np.ndarray:
    """Frames (T, H, W, 3) uint8 of `env`'s states (see `HUAUVEnv.render`)."""
    track = track_from_states(states)
    with Renderer(scene_model(env, states), env.params, width, height, camera, fan, overlay) as r:
        return r.render_track(track, last=False)


def scene_model(env, states: Any) -> mujoco.MjModel:
    """The MuJoCo model to draw `states` in: the env's own, or for a procedural tank (scenario 0) the
    tank of the first state's layout (one episode's states share it)."""
    if not getattr(env, "procedural", False):
        return env.mj_model
    import jax
    from docrl_jax.envs import layouts
    first = states[0] if isinstance(states, (list, tuple)) else states
    layout = jax.device_get(first.sim.layout)
    if np.ndim(layout.z_min):
        layout = jax.tree.map(lambda x: np.asarray(x)[0], layout)
    return layouts.mj_model(layout)
