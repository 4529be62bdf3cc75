"""The carried wheels (.whl, from ../shared/device/get-wheels.sh) slimmed into .whl_gpu for the GPU machine,
whose carried tree (tracked files and the wheels) must stay under 64 MiB: mujoco's wheel without
`mujoco/experimental` and the Filament renderer (`mujoco/_render_filament*`), mujoco-mjx's wheel without its
test data (`mujoco/mjx/test_data`, 6.5 MiB), which neither training nor evaluation imports (rendering uses
EGL); every other wheel copied as it is, but with --without-render
those only rendering needs (pyopengl, glfw: 3.3 MiB), for a job that draws nothing when the tree has
grown. pip installs the slimmed wheel with --no-deps as the device README says (its RECORD still names
the dropped files; pip does not check them).

    python3 benchmarks/slim_wheels.py [--src .whl] [--out .whl_gpu] [--without-render]
then carry .whl_gpu and install WHEELS=.whl_gpu (benchmarks/gpu_lanes.sh) or `pip install ... .whl_gpu/*.whl`.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import zipfile
from pathlib import Path

DROPPED = ("mujoco/experimental/", "mujoco/_render_filament", "mujoco/mjx/test_data/")
RENDER_ONLY = ("pyopengl-", "glfw-")   # wheel names, lower-case


def slim(src: Path, out: Path) -> int:
    """Copies `src` to `out` without the DROPPED entries; returns how many it dropped."""
    dropped = 0
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            if item.filename.startswith(DROPPED):
                dropped += 1
                continue
            zout.writestr(item, zin.read(item.filename))
    return dropped


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--src", default=".whl")
    ap.add_argument("--out", default=".whl_gpu")
    ap.add_argument("--without-render", action="store_true", help="leave out the wheels only rendering needs")
    args = ap.parse_args(argv)
    src, out = Path(args.src), Path(args.out)
    wheels = sorted(w for w in src.glob("*.whl")
                    if not (args.without_render and w.name.lower().startswith(RENDER_ONLY)))
    if not wheels:
        ap.exit(2, f"slim_wheels.py: error: no wheels in {src} (bash ../shared/device/get-wheels.sh makes them)\n")
    out.mkdir(exist_ok=True)
    for wheel in wheels:
        if wheel.name.startswith(("mujoco-", "mujoco_mjx-")):
            print(f"{wheel.name}: {slim(wheel, out / wheel.name)} files dropped")
        else:
            shutil.copy2(wheel, out / wheel.name)
    total = sum(p.stat().st_size for p in out.glob("*.whl"))
    print(f"{out}: {len(wheels)} wheels, {total / 2**20:.1f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
