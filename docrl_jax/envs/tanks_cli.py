"""`docrl tanks` (`python -m docrl_jax.tanks`): the packaged tanks, and tank files checked before they are
flown (docs/TANKS.md).

    docrl tanks list                          # the gallery: each packaged tank's name and description
    docrl tanks check my_tank.yaml more/*.yaml

`check` loads each file as a run or an evaluation would (`tanks.load`: every rule of docs/TANKS.md,
the routes both ways included) and prints one line per file: what it holds, or its one-line error.
Exit status 0 when every file is a valid tank, 2 otherwise.
"""

from __future__ import annotations

import sys
from typing import Sequence

from docrl_jax.arguments import OneLineParser, prog


def build_parser() -> OneLineParser:
    p = OneLineParser(prog=prog("tanks"), description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="action", metavar="ACTION", required=True, parser_class=OneLineParser)
    sub.add_parser("list", help="the packaged tanks (the gallery): name and description")
    check = sub.add_parser("check", help="load and check tank files, one line each")
    check.add_argument("files", nargs="+", metavar="FILE", help="tank files (YAML or JSON)")
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


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.action == "list":
        return list_gallery()
    return check_files(args.files)


if __name__ == "__main__":
    sys.exit(main())
