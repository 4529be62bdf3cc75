"""The tracked tree stays small: at most 25 MB in all, `benchmarks/results/` at most 300 files and
summaries only (no archive, trained policy or long log: those live in git's history, indexed by
docs/results-archive.md)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MAX_TREE_BYTES = 25_000_000
MAX_RESULTS_FILES = 300
RESULTS = "benchmarks/results/"
# Archives and trained policies, by name; a log only when long (a short one can be a summary).
ARCHIVE = re.compile(r"(^|/)raw\.[^/]*$|\.(tar|tar\.gz|tgz|gz|zip|xz|bz2|zst|7z|npz|npy|pkl|pickle|msgpack)$")
LOG = re.compile(r"\.log$")
MAX_LOG_BYTES = 16_000


def problems(files: list[tuple[str, int]]) -> list[str]:
    """Everything that makes the tracked `files` ((path, bytes), paths relative to the root) too large
    or puts raw evidence in `benchmarks/results/`; empty when the tree is as it should be."""
    found = []
    total = sum(size for _, size in files)
    if total > MAX_TREE_BYTES:
        found.append(f"the tracked tree holds {total:,} bytes, more than {MAX_TREE_BYTES:,}")
    results = [(path, size) for path, size in files if path.startswith(RESULTS)]
    if len(results) > MAX_RESULTS_FILES:
        found.append(f"{RESULTS} holds {len(results)} files, more than {MAX_RESULTS_FILES}")
    for path, size in results:
        if ARCHIVE.search(path):
            found.append(f"raw archive in {RESULTS}: {path} (git rm it; index it in docs/results-archive.md)")
        elif LOG.search(path) and size > MAX_LOG_BYTES:
            found.append(f"log of {size:,} bytes in {RESULTS}: {path} (keep a summary, index the log)")
    return found


def tracked_files() -> list[tuple[str, int]]:
    """(path, bytes) of every file git tracks in this checkout; skips the test outside one."""
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    proc = subprocess.run(["git", "-C", str(ROOT), "ls-files", "-z"], capture_output=True)
    if proc.returncode != 0 or not proc.stdout:
        pytest.skip("not a git checkout (an sdist or an unpacked copy): nothing tracked to measure")
    files = []
    for path in proc.stdout.decode().split("\0"):
        full = ROOT / path
        if path and full.is_file():   # a file deleted but not yet committed has no size
            files.append((path, os.lstat(full).st_size))
    return files


def test_the_tracked_tree_is_small_and_results_hold_summaries():
    assert problems(tracked_files()) == []


def test_each_check_can_fail():
    """A tree that breaks each rule once gets one problem per rule, and a clean one none."""
    clean = [("README.md", 1_000), (RESULTS + "h200/x/README.md", 2_000), (RESULTS + "h200/x/short.log", 500)]
    assert problems(clean) == []
    broken = {
        "bytes": clean + [("docs/media/big.gif", MAX_TREE_BYTES)],
        "files": clean + [(f"{RESULTS}h200/x/t{i}.md", 10) for i in range(MAX_RESULTS_FILES)],
        "raw archive": clean + [(RESULTS + "h200/x/raw.tar.gz", 10)],
        "log of": clean + [(RESULTS + "h200/x/sweep.log", MAX_LOG_BYTES + 1)],
    }
    for rule, files in broken.items():
        found = problems(files)
        assert len(found) == 1 and rule in found[0], (rule, found)
    for name in ("policies.npz", "runs.tgz", "console.log.gz", "raw.json"):
        assert any("raw archive" in p for p in problems(clean + [(RESULTS + "h200/x/" + name, 10)])), name
    assert problems(clean + [("docrl_jax/pretrained/td3_lstm.npz", 10)]) == []   # outside the results
