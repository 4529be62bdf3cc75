"""A tank drawn from above (matplotlib): what `docrl tanks draw` writes and the left half of the gallery's
pictures (benchmarks/tank_pictures.py, docs/TANKS.md "The gallery").

Every solid's footprint is shaded by the height of its top (hatched: a solid that does not stand on the
floor, such as a slab, a curtain or a pipe); the air and water regions are dashed; the A-W route is
`flyability.route_path` down the distance field to the water region, from the air region's free point
nearest its centre (`Layout.clear[0]`, where `tanks.load` keeps it), orange in air and blue under water.
The title gives both trips' route length and detour ratio (`flyability.check`: route length / straight
line).

    from docrl_jax.envs import make_params, tank_picture, tanks
    p = make_params(0)
    layout = tanks.load("my_tank.yaml", p)
    path, route = tank_picture.route_of(layout, p)
    rgb = tank_picture.top_view("my_tank", layout, path, route, size_px=720)   # (720, 720, 3) uint8

No OpenGL: the figure is drawn by matplotlib's Agg canvas, without pyplot (no global figure or backend).
"""

from __future__ import annotations

import numpy as np

TOP_SPAN = (-3.6, 5.4)        # m: the colour scale of a solid's top, the same in every picture
AIR_RGB, WATER_RGB = "#e8841a", "#1f6fd1"
FIGURE_INCHES = 3.6           # the figure's side: fonts and lines keep their size, size_px sets the dpi


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
    """(A-W polyline (k, 3) without its repeated tail, flyability.Route of both trips)."""
    import jax

    from docrl_jax.envs import flyability
    route = jax.device_get(flyability.check(layout, p))
    field = flyability.distance_field(flyability.free_cells(layout, p), flyability.region_cells(layout, p, 1))
    path = np.asarray(flyability.route_path(field, layout.clear[0]))
    keep = np.concatenate([[True], np.any(np.diff(path, axis=0) != 0, -1)])
    return path[keep], route


def top_view(name: str, layout, path, route, size_px: int = 360) -> np.ndarray:
    """The top view as an RGB array (size_px, size_px, 3) uint8; `path` and `route` from `route_of`."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import LineCollection
    from matplotlib.colorbar import Colorbar
    from matplotlib.figure import Figure
    from matplotlib.patches import Polygon, Rectangle

    from docrl_jax.envs import layouts
    floor = float(layouts.floor_top(layout))
    cmap, norm = matplotlib.colormaps["viridis"], matplotlib.colors.Normalize(*TOP_SPAN)
    fig = Figure(figsize=(FIGURE_INCHES, FIGURE_INCHES), dpi=size_px / FIGURE_INCHES)
    canvas = FigureCanvasAgg(fig)
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
    bar = Colorbar(cax, cmap=cmap, norm=norm)
    bar.set_label("top of a solid, z (m); hatched: not on the floor", fontsize=5, labelpad=1)
    bar.ax.tick_params(labelsize=5, length=2, pad=1)
    canvas.draw()
    return np.array(canvas.buffer_rgba())[..., :3]
