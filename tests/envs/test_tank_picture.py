"""A tank drawn from above (docrl_jax/envs/tank_picture.py, `docrl tanks draw`): the footprints against the
tank files' own numbers; the command's PNG read back (its signature, its size, the route's colours in
it); a file that is not a tank gets one line, exit status 2 and no picture; a bad --out is one line before
any tank is loaded.

Compiled programs: the loader's check and the route (one parameter set)."""

from __future__ import annotations

import numpy as np
import pytest

from docrl_jax import commands
from docrl_jax.envs import make_params, tank_picture, tanks
from docrl_jax.envs.tanks_cli import DRAW_PX

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _area(poly: np.ndarray) -> float:
    x, y = poly.T
    return 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))


def _expected(name: str) -> list[tuple[float, float, float]]:
    """(xy area, z low, z high) of every solid of a packaged tank file, from its own numbers: a box's
    rectangle (it is not rotated), a capsule's stadium of its ends' circles (it lies level)."""
    out = []
    for s in tanks.read(tanks.files(name)[0])["solids"]:
        if s["type"] == "box":
            (hx, hy, hz), z = s["half_extents"], s["center"][2]
            out.append((4 * hx * hy, z - hz, z + hz))
        else:
            a, b, r = np.array(s["from"]), np.array(s["to"]), s["radius"]
            out.append((2 * r * np.linalg.norm(b[:2] - a[:2]) + np.pi * r ** 2,
                        min(a[2], b[2]) - r, max(a[2], b[2]) + r))
    return sorted(out)


@pytest.mark.parametrize("name", ["wall_opening_mid", "pipe_rack"])
def test_footprints_are_the_files_solids(name):
    got = sorted((_area(poly), lo, hi) for poly, lo, hi in tank_picture.footprints(tanks.load(
        tanks.files(name)[0], make_params(0))))
    want = _expected(name)
    assert len(got) == len(want)
    # The capsule's circles are 23-gons in the drawing: 1.3% less area than the circle.
    np.testing.assert_allclose(np.array(got), np.array(want), rtol=0.015, atol=1e-4)


def test_draw_writes_the_top_view_of_a_gallery_tank(tmp_path, capsys):
    from matplotlib import image
    target = tmp_path / "pictures" / "wall.png"
    assert commands.main(["tanks", "draw", "wall_opening_mid", "--out", str(target)]) == 0
    assert capsys.readouterr().out.splitlines() == [f"wrote {target}"]
    assert target.read_bytes()[:8] == PNG_SIGNATURE
    rgb = (image.imread(target)[..., :3] * 255).round().astype(np.uint8)
    assert rgb.shape == (DRAW_PX, DRAW_PX, 3)
    colours = {tuple(c) for c in rgb.reshape(-1, 3)}
    assert len(colours) > 50                       # solids, regions, route, colour bar: not a blank page
    for hex_rgb in (tank_picture.AIR_RGB, tank_picture.WATER_RGB):   # the route, in air and under water
        rgb_of = tuple(int(hex_rgb[i:i + 2], 16) for i in (1, 3, 5))
        assert np.all(rgb == rgb_of, axis=-1).sum() > 100, hex_rgb


def test_a_file_that_is_not_a_tank_is_one_line_and_no_picture(tmp_path, capsys):
    (tmp_path / "words.yaml").write_text("just some words\n")
    out = tmp_path / "pictures"
    assert commands.main(["tanks", "draw", str(tmp_path / "words.yaml"), "--out", str(out)]) == 2
    printed = capsys.readouterr()
    assert printed.out.splitlines() == [
        f"invalid: {tmp_path / 'words.yaml'}: a tank file holds a mapping of keys (name, description, floor_top, "
        "air, water, solids), not str"]
    assert printed.err == ""
    assert not out.exists()


@pytest.mark.parametrize("argv, problem", [
    (["wall_opening_mid", "--out", "{tmp}/wall.jpg"],
     "--out {tmp}/wall.jpg: a picture is a .png file, or give a folder (one <tank>.png each)"),
    (["gallery", "--out", "{tmp}/all.png"],
     "--out {tmp}/all.png: {n} tanks are drawn into a folder, not into one .png file"),
])
def test_a_bad_out_is_one_line_and_nothing_written(tmp_path, capsys, argv, problem):
    argv = [a.format(tmp=tmp_path) for a in argv]
    problem = problem.format(tmp=tmp_path, n=len(tanks.packaged_names()))
    with pytest.raises(SystemExit) as e:
        commands.main(["tanks", "draw", *argv])
    assert e.value.code == 2
    assert capsys.readouterr().err.splitlines() == [f"python -m docrl_jax.tanks: error: {problem}"]
    assert list(tmp_path.iterdir()) == []
