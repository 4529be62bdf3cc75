"""`docrl tanks` (`python -m docrl_jax.tanks`): the packaged tanks, tank files checked before they are
flown, and tanks drawn (docs/TANKS.md).

    docrl tanks list                          # the gallery: each packaged tank's name and description
    docrl tanks check my_tank.yaml more/*.yaml
    docrl tanks draw my_tank.yaml --out out/my_tank.png
    docrl tanks draw my_tank.yaml wall_opening_mid --out out/pictures    # a folder: <tank>.png each

`check` loads each file as a run or an evaluation would (`tanks.load`: every rule of docs/TANKS.md,
the routes both ways included) and prints one line per file: what it holds, or its one-line error.
`draw` loads each tank the same way (a file, a folder, a packaged tank's name or gallery) and writes its
top view as a PNG (docrl_jax.envs.tank_picture: the solids shaded by the height of their top, the regions,
the A-W route), printing `wrote PATH`; a tank that is not valid gets its one-line error and no picture.
Exit status 0 when every file is a valid tank, 2 otherwise.
"""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Sequence

from docrl_jax.arguments import OUT_HELP, OneLineParser, UsageError, check_out, prog

DRAW_PX = 720   # the top view's side in pixels: its fonts and lines drawn at 200 dpi


def build_parser() -> OneLineParser:
    p = OneLineParser(prog=prog("tanks"), description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True, parser_class=OneLineParser)
    sub.add_parser("list", help="the packaged tanks (the gallery): name and description")
    check = sub.add_parser("check", help="load and check tank files, one line each")
    check.add_argument("files", nargs="+", metavar="FILE", help="tank files (YAML or JSON)")
    draw = sub.add_parser("draw", help="draw tanks from above as PNG pictures")
    draw.add_argument("files", nargs="+", metavar="FILE",
                      help="tank files (YAML or JSON), folders of them, packaged tanks' names or gallery")
    # The shared --out; docrl_jax.flags sits on a floor above the env's (tests/test_imports.py), so its help
    # stem comes from where both read it.
    draw.add_argument("--out", required=True, metavar="PATH",
                      help=f"{OUT_HELP}: a .png file for one tank, else a folder (one <tank>.png each)")
    return p


def list_gallery() -> int:
    from docrl_jax.envs import tanks
    folder = tanks.packaged_dir()
    names = tanks.packaged_names()
    width = max(map(len, names), default=0)
    for name in names:
        data = tanks.read(folder / f"{name}.yaml")
        print(f"{name:<{width}}  {data.get('description', '')}".rstrip())
    print(f"{len(names)} tanks in {folder} (fly them all with --tank gallery)")
    return 0


def check_files(files: Sequence[str]) -> int:
    from docrl_jax.envs import make_params, tanks
    params = make_params(0)
    bad = 0
    for name in files:
        try:
            tanks.load(name, params)
            data = tanks.read(tanks.files(name)[0])
        except tanks.TankError as e:
            bad += 1
            print(f"invalid: {e}", flush=True)
            continue
        solids = [s.get("type") for s in data.get("solids") or []]
        print(f"ok: {name}: {data.get('name', tanks.files(name)[0].stem)!s}, {solids.count('box')} boxes, "
              f"{solids.count('capsule')} capsules, routes both ways", flush=True)
    if bad:
        print(f"{bad} of {len(files)} files are not valid tanks (docs/TANKS.md)", file=sys.stderr)
    return 2 if bad else 0


def draw_out(out: str) -> tuple[Path, bool]:
    """(--out checked, whether it is a folder): an existing folder or a path without a suffix is a folder
    (one <tank>.png each), a .png path the picture of one tank; UsageError otherwise."""
    path = Path(out)
    folder = path.is_dir() or not path.suffix
    if not folder and path.suffix.lower() != ".png":
        raise UsageError(f"--out {out}: a picture is a .png file, or give a folder (one <tank>.png each)")
    return check_out(path, folder=folder), folder


def draw_files(specs: Sequence[str], out: Path, folder: bool) -> int:
    """Each tank of `specs` drawn into `out` (`draw_out`); one line per tank: `wrote PATH` or its error.
    UsageError, before any tank is loaded, when several tanks would go into one .png file."""
    from matplotlib import image

    from docrl_jax.envs import make_params, tank_picture, tanks
    found, errors = [], []
    for spec in specs:
        try:
            found += tanks.files(spec)
        except tanks.TankError as e:
            errors.append(e)
    if not folder and len(found) > 1:
        raise UsageError(f"--out {out}: {len(found)} tanks are drawn into a folder, not into one .png file")
    for e in errors:
        print(f"invalid: {e}", flush=True)
    params = make_params(0)
    bad = len(errors)
    for name in found:
        try:
            layout = tanks.load(name, params)
        except tanks.TankError as e:
            bad += 1
            print(f"invalid: {e}", flush=True)
            continue
        path, route = tank_picture.route_of(layout, params)
        target = out / f"{name.stem}.png" if folder else out
        target.parent.mkdir(parents=True, exist_ok=True)
        image.imsave(target, tank_picture.top_view(name.stem, layout, path, route, size_px=DRAW_PX))
        print(f"wrote {target}", flush=True)
    return 2 if bad else 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.action == "list":
        return list_gallery()
    if args.action == "check":
        return check_files(args.files)
    try:
        return draw_files(args.files, *draw_out(args.out))
    except UsageError as e:
        parser.error(str(e))


if __name__ == "__main__":
    from docrl_jax.console import run_main
    run_main(main)
