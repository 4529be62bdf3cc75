"""The documentation site: `mkdocs build --strict` passes (a broken link, anchor, missing page or
docstring reference fails it), its nav holds every page, CI installs what it needs, and the API
reference's layout table names every module of the package."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parent.parent
needs_mkdocs = pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                                  reason="mkdocs is not installed (pip install -e '.[docs]')")


def build(config: Path, site: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}   # Material's notice about MkDocs 2.0, not about us
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(config),
                           "-d", str(site)], capture_output=True, text=True, timeout=300, env=env)


def nav_pages(nav) -> list[str]:
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, dict):
        return [p for v in nav.values() for p in nav_pages(v)]
    return [p for item in nav for p in nav_pages(item)]


@needs_mkdocs
def test_the_site_builds_strict(tmp_path):
    proc = build(ROOT / "mkdocs.yml", tmp_path / "site")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    home = (tmp_path / "site" / "index.html").read_text()
    assert "<h1 id=\"docrl_jax\">docrl_jax" in home and 'href="TRAINER/"' in home   # the README, its links made the site's
    api = (tmp_path / "site" / "api" / "envs" / "index.html").read_text()
    assert "docrl_jax.envs.make" in api and "Builds the environment" in api   # rendered from the docstring


@needs_mkdocs
def test_a_broken_link_fails_the_build(tmp_path):
    """The same hooks and validation on a two-page site whose page links a file that does not exist."""
    docs = tmp_path / "docs"
    docs.mkdir()
    (tmp_path / "README.md").write_text("# Home\n\n[page](docs/PAGE.md), [code](src/tool.py)\n")
    (tmp_path / "src").mkdir()
    (tmp_path / "src" / "tool.py").write_text("")
    (docs / "PAGE.md").write_text("# Page\n\n[home](../README.md)\n")
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    config = {"site_name": "t", "docs_dir": "docs", "hooks": [str(ROOT / "docs" / "hooks.py")],
              "validation": config["validation"], "nav": ["index.md", "PAGE.md"]}
    (tmp_path / "mkdocs.yml").write_text(yaml.safe_dump(config))
    ok = build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert (tmp_path / "site" / "_repo" / "src" / "tool.py").exists()
    (docs / "PAGE.md").write_text("# Page\n\n[gone](../src/gone.py)\n")
    broken = build(tmp_path / "mkdocs.yml", tmp_path / "site")
    assert broken.returncode != 0 and "gone.py" in broken.stdout + broken.stderr


def test_the_nav_holds_every_page():
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    nav = set(nav_pages(config["nav"]))
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").glob("*.md")}
    pages |= {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs" / "api").glob("*.md")}
    assert "index.md" in nav and not pages - nav, f"not in mkdocs.yml's nav: {sorted(pages - nav)}"
    missing = sorted(p for p in nav - {"index.md"} if not (ROOT / "docs" / p).is_file())
    assert not missing, f"in mkdocs.yml's nav but not in docs/: {missing}"


def test_ci_installs_the_docs_packages():
    """The `test` extra (what .ci/run and the README install) holds the `docs` extra, so CI never skips
    the build."""
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert extras["docs"] and not set(extras["docs"]) - set(extras["test"])


def test_the_layout_table_names_every_module():
    text = (ROOT / "docs" / "api" / "index.md").read_text()
    layout = text[text.index("## Layout"):]
    missing = []
    for path in sorted((ROOT / "docrl_jax").rglob("*.py")):
        rel = path.relative_to(ROOT)
        if path.name in ("__init__.py", "__main__.py") and rel.parent.name != "envs":
            continue  # a package's face and entry point: the package's row names them
        folder = rel.parent.as_posix()
        rows = [line for line in layout.splitlines() if line.startswith("|") and folder in line]
        if not any(re.search(rf"\b{re.escape(path.name)}\b|\b{re.escape(path.stem)}\b", row) for row in rows):
            missing.append(rel.as_posix())
    assert not missing, f"docs/api/index.md's layout table does not name: {missing}"
