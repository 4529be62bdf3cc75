"""One picture per tank file (docs/TANKS.md, "The gallery"): a top view beside MuJoCo's overview.

The top view is docrl_jax.envs.tank_picture's, as `docrl tanks draw` writes it: every solid's footprint
shaded by the height of its top (hatched: a solid that does not stand on the floor), the air and water
regions (dashed), the A-W route (orange in air, blue under water), and in the title both trips' route
length and detour ratio. The overview is `rendering.Renderer`'s overview camera on
`layouts.mj_model(layout)` with the same route drawn as the vehicle's trail and the vehicle at its start.

    MUJOCO_GL=egl python benchmarks/tank_pictures.py --out docs/media/tanks
    MUJOCO_GL=egl python benchmarks/tank_pictures.py --out /tmp/pics --tanks my_tank.yaml --table

JPEG, 900 x 360 pixels, 25-50 KB each. Each tank's line (stderr) also gives the time the drawn route takes at
the vehicle's top speeds. `--table` prints the gallery's markdown table rows (name, family, lengths,
ratios). CPU is enough (~5 s a tank on 2 shared cores).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

FAMILIES = ("wall", "zigzag", "dead_end", "room", "ceiling", "pier", "pipe", "grove", "mixed")


def family(name: str) -> str:
    """The tank's family: the known prefix of its name (docs/TANKS.md's families), else its first word."""
    return next((f for f in FAMILIES if name == f or name.startswith(f + "_")), name.split("_")[0])


def top_speed_time(path, p) -> float:
    """Seconds to fly `path` at the vehicle's top speeds, horizontal and vertical at once (a lower bound
    on any flight along it; an episode lasts max_episode_steps * control_dt)."""
    step = np.diff(path, axis=0)
    return float(np.sum(np.maximum(np.linalg.norm(step[:, :2], axis=1) / p.max_forward_speed,
                                   np.abs(step[:, 2]) / p.max_vertical_speed)))


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
    from docrl_jax.envs.tank_picture import route_of, top_view
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
