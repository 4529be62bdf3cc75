"""One picture per tank file (docs/TANKS.md, "The gallery"): a top view beside MuJoCo's overview.

The top view (matplotlib) shows every solid's footprint shaded by the height of its top (hatched: a solid
that does not stand on the floor, such as a slab, a curtain or a pipe), the air and water regions (dashed),
and the A-W route: `flyability.route_path` down the distance field to the water region, from the air
region's free point nearest its centre (`Layout.clear[0]`, where `tanks.load` keeps it), orange in air and
blue under water. The overview is `rendering.Renderer`'s overview camera on `layouts.mj_model(layout)`
with the same route drawn as the vehicle's trail and the vehicle at its start. The title gives both
trips' mean route length and detour ratio (`flyability.check`: route length / straight line).

    MUJOCO_GL=egl python benchmarks/tank_pictures.py --out docs/media/tanks
    MUJOCO_GL=egl python benchmarks/tank_pictures.py --out /tmp/pics --tanks my_tank.yaml --table

JPEG, 900 x 360 pixels, 25-50 KB each. Each tank's line (stderr) also gives the time the drawn route takes at
the vehicle's top speeds. `--table` prints the gallery's markdown table rows (name, family, lengths,
ratios). CPU is enough (~5 s a tank on 2 shared cores).
"""

from __future__ import annotations

import argparse
import io
import os
import sys
from pathlib import Path

import numpy as np

FAMILIES = ("wall", "zigzag", "dead_end", "room", "ceiling", "pier", "pipe", "grove", "mixed")
TOP_SPAN = (-3.6, 5.4)        # m: the colour scale of a solid's top, the same in every picture
AIR_RGB, WATER_RGB = "#e8841a", "#1f6fd1"


def family(name: str) -> str:
    """The tank's family: the known prefix of its name (docs/TANKS.md's families), else its first word."""
    return next((f for f in FAMILIES if name == f or name.startswith(f + "_")), name.split("_")[0])


def footprints(layout):
    """Per obstacle slot in use: (xy polygon (k, 2), z low, z high). Boxes: the hull of their 8 corners;
    capsules: the hull of the circles around both ends."""
    from scipy.spatial import ConvexHull

    from docrl_jax.envs import layouts
    solids = layouts.obstacles(layout)
    out = []
    signs = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T
    for pos, rot, half in zip(*(np.asarray(x, np.float64) for x in (solids.box_pos, solids.box_rot, solids.box_half))):
        if pos[2] < -40:          # a parked slot
            continue
        corners = pos + (signs * half) @ rot.T
        out.append((corners[ConvexHull(corners[:, :2]).vertices, :2], corners[:, 2].min(), corners[:, 2].max()))
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, 24)), np.sin(np.linspace(0, 2 * np.pi, 24))], -1)
    for a, b, r in zip(*(np.asarray(x, np.float64) for x in (solids.cap_a, solids.cap_b, solids.cap_radius))):
        if min(a[2], b[2]) < -40:
            continue
        pts = np.concatenate([a[:2] + r * ring, b[:2] + r * ring])
        out.append((pts[ConvexHull(pts).vertices], min(a[2], b[2]) - r, max(a[2], b[2]) + r))
    return out


def route_of(layout, p):
    """(A-W polyline (k, 3) without its repeated tail, flyability.Route)."""
    import jax

    from docrl_jax.envs import flyability
    route = jax.device_get(flyability.check(layout, p))
    field = flyability.distance_field(flyability.free_cells(layout, p), flyability.region_cells(layout, p, 1))
    path = np.asarray(flyability.route_path(field, layout.clear[0]))
    keep = np.concatenate([[True], np.any(np.diff(path, axis=0) != 0, -1)])
    return path[keep], route


def top_speed_time(path, p) -> float:
    """Seconds to fly `path` at the vehicle's top speeds, horizontal and vertical at once (a lower bound
    on any flight along it; an episode lasts max_episode_steps * control_dt)."""
    step = np.diff(path, axis=0)
    return float(np.sum(np.maximum(np.linalg.norm(step[:, :2], axis=1) / p.max_forward_speed,
                                   np.abs(step[:, 2]) / p.max_vertical_speed)))


def top_view(name, layout, path, route, size_px: int = 360):
    """The top view as an RGB array (size_px, size_px, 3)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.patches import Polygon, Rectangle

    from docrl_jax.envs import layouts
    floor = float(layouts.floor_top(layout))
    cmap, norm = plt.get_cmap("viridis"), matplotlib.colors.Normalize(*TOP_SPAN)
    fig = plt.figure(figsize=(size_px / 100, size_px / 100), dpi=100)
    ax = fig.add_axes((0.08, 0.09, 0.74, 0.75))
    cax = fig.add_axes((0.85, 0.09, 0.03, 0.75))
    ax.add_patch(Rectangle((-4.9, -4.9), 9.8, 9.8, fill=True, fc="#dfeef0", ec="k", lw=1.0))
    for poly, lo, hi in sorted(footprints(layout), key=lambda s: s[2]):
        standing = lo <= floor + 0.05
        ax.add_patch(Polygon(poly, closed=True, fc=cmap(norm(hi)), ec="k", lw=0.4,
                             alpha=0.85 if standing else 0.5, hatch=None if standing else "////"))
    regions = np.asarray(layout.regions)
    for (lo, hi), rgb in ((regions[0], AIR_RGB), (regions[1], WATER_RGB)):
        ax.add_patch(Rectangle(lo[:2], *(hi[:2] - lo[:2]), fill=False, ec=rgb, lw=1.4, ls="--"))
    # The route under water drawn wide and below, the route in air narrow on top: both show where they overlap.
    seg = np.stack([path[:-1, :2], path[1:, :2]], 1)
    wet = (path[:-1, 2] + path[1:, 2]) / 2 < 0
    ax.add_collection(LineCollection(seg[wet], colors=WATER_RGB, lw=2.6, zorder=3))
    ax.add_collection(LineCollection(seg[~wet], colors=AIR_RGB, lw=1.5, zorder=4))
    ax.plot(*path[0, :2], marker="^", color=AIR_RGB, mec="k", ms=6, zorder=5)
    ax.plot(*path[-1, :2], marker="o", color=WATER_RGB, mec="k", ms=6, zorder=5)
    ax.set_xlim(-5.1, 5.1)
    ax.set_ylim(-5.1, 5.1)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=5, length=2, pad=1)
    ax.set_xlabel("x (m)", fontsize=6, labelpad=1)
    ax.set_ylabel("y (m)", fontsize=6, labelpad=1)
    length, ratio = np.asarray(route.length), np.asarray(route.length) / np.asarray(route.straight)
    (air_lo, air_hi), (water_lo, water_hi) = regions
    ax.set_title(f"{name}  (floor {floor:.1f} m)\nA-W {length[0]:.1f} m (x{ratio[0]:.2f})   "
                 f"W-A {length[1]:.1f} m (x{ratio[1]:.2f})\nair z {air_lo[2]:.1f}..{air_hi[2]:.1f} (orange), "
                 f"water z {water_lo[2]:.1f}..{water_hi[2]:.1f} (blue)", fontsize=6.5, pad=3)
    bar = matplotlib.colorbar.ColorbarBase(cax, cmap=cmap, norm=norm)
    bar.set_label("top of a solid, z (m); hatched: not on the floor", fontsize=5, labelpad=1)
    bar.ax.tick_params(labelsize=5, length=2, pad=1)
    buf = io.BytesIO()
    fig.savefig(buf, format="rgba", dpi=100)
    plt.close(fig)
    w, h = fig.canvas.get_width_height()
    return np.frombuffer(buf.getvalue(), np.uint8).reshape(h, w, 4)[..., :3]


def overview(layout, path, p, width: int = 540, height: int = 360):
    """MuJoCo's overview of the tank (H, W, 3), the route as the trail, the vehicle at its start."""
    from docrl_jax.envs import layouts, rendering
    qpos = np.concatenate([path[0], [1.0, 0.0, 0.0, 0.0]])
    with rendering.Renderer(layouts.mj_model(layout), p, width, height, camera="overview", fan=False,
                            overlay=False) as r:
        return r.frame(qpos, path[-1], trail=path)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="folder of the pictures (<tank>.jpg)")
    ap.add_argument("--tanks", nargs="*", default=["gallery"],
                    help="tank files, folders or packaged names (default: the gallery)")
    ap.add_argument("--goal-clearance", type=float, default=None,
                    help="env goal_clearance (default: make_params(0)'s)")
    ap.add_argument("--quality", type=int, default=82, help="JPEG quality")
    ap.add_argument("--table", action="store_true", help="print the gallery's markdown table rows")
    args = ap.parse_args(argv)

    from PIL import Image

    from docrl_jax.envs import tanks
    from docrl_jax.envs.params import make_params
    p = make_params(0) if args.goal_clearance is None else make_params(0, goal_clearance=args.goal_clearance)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    paths = [f for spec in args.tanks for f in tanks.files(spec)]
    rows = []
    for f in paths:
        layout = tanks.load(f, p)
        path, route = route_of(layout, p)
        picture = np.concatenate([top_view(f.stem, layout, path, route), overview(layout, path, p)], axis=1)
        target = out / f"{f.stem}.jpg"
        Image.fromarray(picture).save(target, quality=args.quality, optimize=True)
        length, ratio = np.asarray(route.length), np.asarray(route.length) / np.asarray(route.straight)
        rows.append(f"| `{f.stem}` | {family(f.stem)} | {length[0]:.1f} / {length[1]:.1f} | "
                    f"{ratio[0]:.2f} / {ratio[1]:.2f} |")
        print(f"{target} ({os.path.getsize(target) / 1024:.0f} KB): A-W {length[0]:.1f} m x{ratio[0]:.2f}, "
              f"W-A {length[1]:.1f} m x{ratio[1]:.2f}; the drawn route at top speed {top_speed_time(path, p):.0f} s",
              file=sys.stderr, flush=True)
    if args.table:
        print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
