"""MkDocs hooks (mkdocs.yml `hooks:`): the repository's README is the site's home page, and every page
keeps the links that work on the repository's own file view.

The pages are written to be read in the repository, so their relative links name repository paths:
the README links `docs/TRAINER.md` and `docrl_jax/envs/params.py`, a page under docs/ links
`../examples/deploy_node.py`. Here each such link is rewritten for the site: a docs page to that
page, any other file to a copy of it under `_repo/` (served as it is, Markdown included). A link to
a folder goes to its README.md. A link whose target is not in the repository is left as written, so
`mkdocs build --strict` fails on it.
"""

from __future__ import annotations

import os
import re
from pathlib import Path, PurePosixPath

from mkdocs.structure.files import File, Files

# Inline links and images, [text](target) and ![alt](target "title"); reference links are not used.
LINK = re.compile(r"(!?\[[^\]]*\]\()([^)\s]+)((?:\s+\"[^\"]*\")?\))")
FENCE = re.compile(r"^(```|~~~).*?^\1", re.M | re.S)
REPO_COPY = "_repo"


class _SourceFile(File):
    """A repository file served as it is (a README.md among them is not rendered as a page)."""

    def is_documentation_page(self) -> bool:
        return False


def _root(config) -> Path:
    return Path(config.config_file_path).resolve().parent


def _docs(config) -> Path:
    return Path(config.docs_dir).resolve()


def _real_source(file: File, config) -> Path:
    return Path(file.abs_src_path).resolve()


def _site_target(target: str, source: Path, root: Path, docs: Path) -> str | None:
    """The docs-relative path a relative link `target` of the file `source` lands on in the site, or
    None when it is not a relative link to something that exists in the repository."""
    if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I) or target.startswith(("#", "/")):
        return None
    path = target.split("#", 1)[0]
    if not path:
        return None
    real = (source.parent / path).resolve()
    if real.is_dir() and (real / "README.md").is_file() and not real.is_relative_to(docs):
        real = real / "README.md"
    if not real.is_file() or not real.is_relative_to(root):
        return None
    if real == root / "README.md" and not (docs / "index.md").exists():
        return "index.md"
    if real.is_relative_to(docs):
        return real.relative_to(docs).as_posix()
    return f"{REPO_COPY}/{real.relative_to(root).as_posix()}"


def _links(markdown: str):
    """(match, target) of every inline link outside fenced code blocks."""
    fences = [m.span() for m in FENCE.finditer(markdown)]
    for m in LINK.finditer(markdown):
        if not any(a <= m.start() < b for a, b in fences):
            yield m, m.group(2)


def on_files(files: Files, config) -> Files:
    root, docs = _root(config), _docs(config)
    if files.get_file_from_path("index.md") is None:
        files.append(File.generated(config, "index.md", abs_src_path=str(root / "README.md")))
    for page in [f for f in files if f.is_documentation_page()]:
        source = _real_source(page, config)
        for _, target in _links(source.read_text(encoding="utf-8")):
            site = _site_target(target, source, root, docs)
            if site and site.startswith(REPO_COPY + "/") and files.get_file_from_path(site) is None:
                real = root / site[len(REPO_COPY) + 1:]
                files.append(_SourceFile.generated(config, site, abs_src_path=str(real)))
    return files


def on_page_markdown(markdown: str, page, config, files: Files) -> str:
    root, docs = _root(config), _docs(config)
    source = _real_source(page.file, config)
    here = PurePosixPath(page.file.src_uri).parent
    out, last = [], 0
    for m, target in _links(markdown):
        site = _site_target(target, source, root, docs)
        if site is None:
            continue
        anchor = "#" + target.split("#", 1)[1] if "#" in target else ""
        new = os.path.relpath(site, here.as_posix() or ".") + anchor
        out += [markdown[last:m.start()], m.group(1), new, m.group(3)]
        last = m.end()
    return "".join(out) + markdown[last:]
