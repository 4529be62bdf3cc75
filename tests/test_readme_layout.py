"""README's layout table names every module of the package, so a newcomer finds each one there."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_readme_layout_lists_every_module():
    text = (ROOT / "README.md").read_text()
    layout = text[text.index("## Layout"):]
    missing = []
    for path in sorted((ROOT / "docrl_jax").rglob("*.py")):
        rel = path.relative_to(ROOT)
        if path.name in ("__init__.py", "__main__.py") and rel.parent.name != "envs":
            continue  # a package's face and entry point: the package's row names them
        folder = f"{rel.parent.as_posix()}/"
        rows = [line for line in layout.splitlines() if line.startswith("|") and folder.rstrip("/") in line]
        if not any(path.name in row or path.stem in row for row in rows):
            missing.append(rel.as_posix())
    assert not missing, f"README's layout table does not name: {missing}"
