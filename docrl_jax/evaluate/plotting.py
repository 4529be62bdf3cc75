"""Figures of trials: trajectories in the tank and the paper's Figure 3 (Matplotlib, Agg, PNG), and
the figure command `python -m docrl_jax.plotting figure3|curves` (learning curves: `curves.py`).

    plot_trajectories(env.mj_model, positions, steps, outcome, start, goal, "traj.png")
    python -m docrl_jax.plotting figure3 results/docrl_d results/bba --scenario 2 --out fig3.png

The tank, floor, obstacles and water surface are read from the scene's MuJoCo model (geoms of group
1 are solids: boxes and capsules; the group-2 plane named water_surface is the surface), so the
figures always show the geometry the simulator used.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

OUTCOME_COLOURS = {0: "tab:green", 1: "tab:red", 2: "tab:orange", 3: "tab:gray", 4: "tab:purple"}
OUTCOME_LABELS = {0: "success", 1: "collision", 2: "out of bounds", 3: "time-out", 4: "diverged"}
Z_TOP = 5.0  # the figures' ceiling (the walls reach 5.4, the bound 4.8)


# ------------------------------------------------------------------------------------ scene

def scene_solids(mj_model) -> dict:
    """Walls, floor and obstacles of a scene, world frame: {'tank': half-width, 'floor_top': z,
    'boxes': [(pos, rot, half)], 'capsules': [(a, b, radius)], 'surface': z or None}."""
    import mujoco
    data = mujoco.MjData(mj_model)
    mujoco.mj_kinematics(mj_model, data)
    boxes, caps, walls = [], [], []
    floor_top, surface = None, None
    for g in range(mj_model.ngeom):
        name = mj_model.geom(g).name
        pos, rot, size = data.geom_xpos[g].copy(), data.geom_xmat[g].reshape(3, 3).copy(), mj_model.geom_size[g].copy()
        if name == "water_surface":
            surface = float(pos[2])
            continue
        if mj_model.geom_group[g] != 1 or mj_model.geom_bodyid[g] != 0:
            continue
        if name.startswith("wall"):
            walls.append((pos, rot, size))
        elif name == "floor":
            floor_top = float(pos[2] + size[2])
        elif mj_model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            boxes.append((pos, rot, size))
        elif mj_model.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = rot[:, 2] * size[1]
            caps.append((pos - axis, pos + axis, float(size[0])))
    # Inner half-width of the tank: the smallest |x| or |y| inner face of the walls.
    faces = []
    for p, _, s in walls:
        axis = int(np.argmax(np.abs(p[:2])))
        faces.append(float(abs(p[axis]) - s[axis]))
    return {"tank": min(faces) if faces else 4.9, "floor_top": floor_top if floor_top is not None else -1.3,
            "boxes": boxes, "capsules": caps, "surface": surface if surface is not None else 0.0}


def _box_corners(pos, rot, half):
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    return pos[None] + (signs * half[None]) @ rot.T


def _hull2d(points: np.ndarray) -> np.ndarray:
    """Convex hull (monotone chain) of 2-D points, counter-clockwise."""
    pts = sorted(map(tuple, np.round(points, 9)))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _clip_segment(a, b, zlo, zhi):
    """The part of segment a-b with z in [zlo, zhi] (None if empty)."""
    t0, t1 = 0.0, 1.0
    d = b - a
    for lo_side, bound in ((True, zlo), (False, zhi)):
        if abs(d[2]) < 1e-12:
            if (a[2] < bound) if lo_side else (a[2] > bound):
                return None
            continue
        t = (bound - a[2]) / d[2]
        if (d[2] > 0) == lo_side:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
    if t0 > t1:
        return None
    return a + t0 * d, a + t1 * d


def draw_scene_xy(ax, solids: dict) -> None:
    h = solids["tank"]
    ax.add_patch(plt.Rectangle((-h, -h), 2 * h, 2 * h, fill=False, ec="0.3", lw=2))
    for pos, rot, half in solids["boxes"]:
        hull = _hull2d(_box_corners(pos, rot, half)[:, :2])
        ax.add_patch(plt.Polygon(hull, closed=True, fc="tab:brown", ec="0.25", alpha=0.7))
    for a, b, r in solids["capsules"]:
        seg = _clip_segment(a, b, solids["floor_top"], Z_TOP)
        if seg is None:
            continue
        th = np.linspace(0, 2 * np.pi, 48)
        circle = np.stack([np.cos(th), np.sin(th)], -1) * r
        pts = np.concatenate([seg[0][None, :2] + circle, seg[1][None, :2] + circle])
        ax.add_patch(plt.Polygon(_hull2d(pts), closed=True, fc="tab:brown", ec="0.25", alpha=0.7))


def draw_scene_3d(ax, solids: dict) -> None:
    h, zf, zs = solids["tank"], solids["floor_top"], solids["surface"]
    # Tank edges
    for z in (zf, Z_TOP):
        ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], [z] * 5, color="0.4", lw=0.8)
    for x, y in ((-h, -h), (h, -h), (h, h), (-h, h)):
        ax.plot([x, x], [y, y], [zf, Z_TOP], color="0.4", lw=0.8)
    # Floor and water surface
    ax.add_collection3d(Poly3DCollection([[(-h, -h, zf), (h, -h, zf), (h, h, zf), (-h, h, zf)]],
                                         facecolor="0.6", alpha=0.25))
    ax.add_collection3d(Poly3DCollection([[(-h, -h, zs), (h, -h, zs), (h, h, zs), (-h, h, zs)]],
                                         facecolor="tab:blue", alpha=0.18))
    faces_idx = [(0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5)]
    for pos, rot, half in solids["boxes"]:
        c = _box_corners(pos, rot, half)
        c[:, 2] = np.clip(c[:, 2], zf, Z_TOP)
        ax.add_collection3d(Poly3DCollection([[c[i] for i in f] for f in faces_idx], facecolor="tab:brown",
                                             edgecolor="0.3", lw=0.2, alpha=0.35))
    for a, b, r in solids["capsules"]:
        seg = _clip_segment(a, b, zf, Z_TOP)
        if seg is None:
            continue
        a, b = seg
        axis = b - a
        length = np.linalg.norm(axis)
        if length < 1e-9:
            continue
        w = axis / length
        u = np.cross(w, [1.0, 0, 0] if abs(w[0]) < 0.9 else [0, 1.0, 0])
        u /= np.linalg.norm(u)
        v = np.cross(w, u)
        th, t = np.meshgrid(np.linspace(0, 2 * np.pi, 24), np.linspace(0, 1, 2))
        pts = a[None, None] + t[..., None] * axis + r * (np.cos(th)[..., None] * u + np.sin(th)[..., None] * v)
        ax.plot_surface(pts[..., 0], pts[..., 1], np.clip(pts[..., 2], zf, Z_TOP), color="tab:brown",
                        alpha=0.3, linewidth=0)


# ------------------------------------------------------------------------------------ trajectories

def _choose(outcome: np.ndarray, k: int) -> list[int]:
    """Up to k trial indices: successes first, then failures, so both kinds appear."""
    ok, bad = list(np.flatnonzero(outcome == 0)), list(np.flatnonzero(outcome != 0))
    k_ok = min(len(ok), max(1, k // 2) if bad else k)
    return ok[:k_ok] + bad[: k - k_ok]


def draw_trajectories(ax3, ax2, solids, positions, steps, outcome, start, goal, max_trajectories=10,
                      arrival_distance=0.5, legend=True) -> list[int]:
    """Scene, trajectories (coloured by outcome), start and goal on a 3-D axis and an x-y axis."""
    positions, steps, outcome = np.asarray(positions), np.asarray(steps), np.asarray(outcome)
    draw_scene_3d(ax3, solids)
    draw_scene_xy(ax2, solids)
    chosen = _choose(outcome, max_trajectories)
    seen = set()
    for i in chosen:
        p = positions[i, : int(steps[i]) + 1]
        c = OUTCOME_COLOURS.get(int(outcome[i]), "k")
        label = None if int(outcome[i]) in seen else OUTCOME_LABELS.get(int(outcome[i]))
        seen.add(int(outcome[i]))
        ax3.plot(p[:, 0], p[:, 1], p[:, 2], color=c, lw=1.2, alpha=0.85)
        ax2.plot(p[:, 0], p[:, 1], color=c, lw=1.2, alpha=0.85, label=label)
        if int(outcome[i]) in (1, 2, 4):
            ax2.plot(p[-1, 0], p[-1, 1], "x", color=c, ms=7, mew=2)
            ax3.scatter(*p[-1], color=c, marker="x", s=30)
    start_kw = dict(color="k", marker="^", s=70, label="start")
    goal_kw = dict(color="gold", marker="*", s=220, edgecolor="k", label="goal")
    ax3.scatter(*start, **start_kw)
    ax3.scatter(*goal, **goal_kw)
    ax2.scatter(start[0], start[1], zorder=5, **start_kw)
    ax2.scatter(goal[0], goal[1], zorder=5, **goal_kw)
    ax2.add_patch(plt.Circle(goal[:2], arrival_distance, fill=False, ls="--", ec="goldenrod"))
    h = solids["tank"]
    ax3.set(xlim=(-h, h), ylim=(-h, h), zlim=(solids["floor_top"], Z_TOP), xlabel="x (m)", ylabel="y (m)",
            zlabel="z (m)")
    ax3.set_box_aspect((2 * h, 2 * h, Z_TOP - solids["floor_top"]))
    ax3.view_init(elev=22, azim=-60)
    ax2.set(xlim=(-h - 0.3, h + 0.3), ylim=(-h - 0.3, h + 0.3), xlabel="x (m)", ylabel="y (m)", aspect="equal")
    ax2.grid(alpha=0.3)
    if legend:
        ax2.legend(loc="upper left", fontsize=8, framealpha=0.85)
    return chosen


def plot_trajectories(mj_model, positions, steps, outcome, start, goal, path, title: str = "",
                      max_trajectories: int = 10, arrival_distance: float = 0.5) -> Path:
    """3-D view and x-y view of up to `max_trajectories` trials (coloured by outcome), tank,
    obstacles, water surface, start and goal. positions (N, T+1, 3), steps (N,), outcome (N,)."""
    outcome = np.asarray(outcome)
    solids = scene_solids(mj_model)
    fig = plt.figure(figsize=(12, 5.6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    chosen = draw_trajectories(ax3, ax2, solids, positions, steps, outcome, start, goal, max_trajectories,
                               arrival_distance)
    n_ok = int((outcome == 0).sum())
    ax2.set_title(f"x-y plane ({len(chosen)} of {len(outcome)} trials shown; {n_ok} successes)", fontsize=10)
    ax3.set_title("3-D (blue: water surface z = 0)", fontsize=10)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_figure3(eval_dirs: Sequence, scenario: int, path, max_trajectories: int = 3,
                 seed_index: int | None = None) -> Path:
    """The paper's Figure 3 from several `python -m docrl_jax.evaluate` output directories: one row
    per method, columns A-W 3-D, A-W x-y, W-A 3-D, W-A x-y, `max_trajectories` trials each.

    Reads each dir's trajectories_s{scenario}_{direction}[_seed{k}].npz and its method name from
    results.json; `seed_index` picks the seed of a multi-seed run (default: the first found); a directory evaluated
    without seeds (a baseline such as BBA) contributes its only trajectories."""
    import json
    import mujoco
    from docrl_jax.envs.huauv import scene_path
    solids = scene_solids(mujoco.MjModel.from_xml_path(scene_path(scenario)))
    eval_dirs = [Path(d) for d in eval_dirs]
    if not eval_dirs:
        raise ValueError("plot_figure3: no evaluation directories given")
    fig = plt.figure(figsize=(18, 4.3 * len(eval_dirs)))
    for row, d in enumerate(eval_dirs):
        try:
            method = json.loads((d / "results.json").read_text())["results"][0]["method"]
        except (OSError, KeyError, IndexError, ValueError):
            method = d.name
        for col, direction in enumerate(("air_to_water", "water_to_air")):
            stem = f"trajectories_s{scenario}_{direction}"
            pattern = f"{stem}_seed{seed_index}.npz" if seed_index is not None else f"{stem}*.npz"
            files = sorted(d.glob(pattern))
            if not files and seed_index is not None:  # a seedless evaluation (a baseline) in the same figure
                files = sorted(d.glob(f"{stem}.npz"))
            if not files:
                raise FileNotFoundError(f"{d}: no {pattern} (run python -m docrl_jax.evaluate --scenarios "
                                        f"{scenario} --out {d})")
            z = np.load(files[0])
            ax3 = fig.add_subplot(len(eval_dirs), 4, 4 * row + 2 * col + 1, projection="3d")
            ax2 = fig.add_subplot(len(eval_dirs), 4, 4 * row + 2 * col + 2)
            draw_trajectories(ax3, ax2, solids, z["positions"], z["steps"], z["outcome"], z["start"], z["goal"],
                              max_trajectories, legend=(row == 0 and col == 0))
            short = "air-water" if direction == "air_to_water" else "water-air"
            n_ok, n = int((z["outcome"] == 0).sum()), len(z["outcome"])
            ax3.set_title(f"{method}, {short}", fontsize=10)
            ax2.set_title(f"{method}, {short}, x-y plane ({n_ok}/{n} success)", fontsize=10)
    fig.suptitle(f"Trajectories, scenario {scenario} (cf. the paper's Figure 3)")
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.4 / fig.get_figheight()))  # keep the first row clear of the title
    return _save(fig, path)


def main(argv: Sequence[str] | None = None) -> int:
    import argparse
    from docrl_jax.evaluate import curves
    p = argparse.ArgumentParser(prog="python -m docrl_jax.plotting", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    f3 = sub.add_parser("figure3", help="Figure 3 from evaluation output dirs (one row per method)")
    f3.add_argument("eval_dirs", nargs="+")
    f3.add_argument("--scenario", type=int, default=2, choices=(1, 2, 3))
    f3.add_argument("--trajectories", type=int, default=3)
    f3.add_argument("--seed-index", type=int, default=None)
    f3.add_argument("--out", required=True, help="the figure file to write, e.g. figure3.png")
    curves.add_command(sub)
    args = p.parse_args(argv)
    try:
        if args.cmd == "figure3":
            print(plot_figure3(args.eval_dirs, args.scenario, args.out, args.trajectories, args.seed_index))
        else:
            curves.run_command(args)
    except (ValueError, FileNotFoundError) as e:   # RunDirError is a ValueError
        p.error(str(e))
    return 0


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
