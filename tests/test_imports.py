"""No import cycles among the package's modules, counting imports inside functions too (a lazy import
hides a cycle from Python but not from a reader), not those under `if TYPE_CHECKING`: each module's
dependencies read one way. And the floors of the house: no module imports one of a floor above its
own (the commands on top, the env at the bottom)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parent.parent / "docrl_jax"


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PKG.parent).with_suffix("").parts)
    if parts[-1] in ("__init__", "__main__"):
        parts = parts[:-1] + ([] if parts[-1] == "__init__" else ["__main__"])
    return ".".join(parts)


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in PKG.rglob("*.py")}
    graph = {m: set() for m in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text())
        for block in [n for n in ast.walk(tree) if isinstance(n, ast.If) and ast.unparse(n.test) == "TYPE_CHECKING"]:
            block.body = []  # annotation-only imports are not executed
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            for t in targets:
                if t in modules and t != name and not name.startswith(t + "."):  # a package's own __init__
                    graph[name].add(t)
    return graph


def _cycle(graph):
    state = {}

    def visit(m, stack):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return stack[stack.index(n):] + [n]
            if n not in state:
                found = visit(n, stack + [n])
                if found:
                    return found
        state[m] = 2
        return None
    for m in sorted(graph):
        if m not in state:
            found = visit(m, [m])
            if found:
                return found
    return None


def test_no_import_cycles():
    graph = _graph()
    assert {"docrl_jax.train.cli", "docrl_jax.train", "docrl_jax.evaluate", "docrl_jax.evaluate.plotting"} <= set(graph)
    assert "docrl_jax.console" in graph["docrl_jax.train.cli"]
    assert "docrl_jax.train.loop" in graph["docrl_jax.train.sweep"]
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


# Floors, bottom first: a module may import its own floor and those below, never one above. The
# first matching prefix names a module's floor.
FLOORS = [
    ["docrl_jax.errors", "docrl_jax.moved", "docrl_jax.schema", "docrl_jax.resources", "docrl_jax.arguments",
     "docrl_jax.console"],
    ["docrl_jax.envs", "docrl_jax.config"],
    ["docrl_jax.networks", "docrl_jax.replay", "docrl_jax.algorithms", "docrl_jax.sharding", "docrl_jax.policy",
     "docrl_jax.baselines"],
    ["docrl_jax.checkpoint", "docrl_jax.memory"],
    ["docrl_jax.runs", "docrl_jax.pretrained"],
    ["docrl_jax.evaluate", "docrl_jax.export", "docrl_jax.flags"],
    ["docrl_jax.train"],
    ["docrl_jax.sweep", "docrl_jax.compare", "docrl_jax.plotting", "docrl_jax.benchmarking", "docrl_jax"],   # command names, the package, the benchmark shelf
]


def _floor(module: str) -> int:
    for i, prefixes in enumerate(FLOORS):
        if any(module == p or module.startswith(p + ".") for p in prefixes if p != "docrl_jax"):
            return i
    assert module == "docrl_jax" or module.count(".") == 1, f"{module}: on no floor; add it to FLOORS"
    return len(FLOORS) - 1


def test_no_import_runs_back_up():
    graph = _graph()
    up = [f"{m} -> {t}" for m, targets in graph.items() for t in targets
          if t != "docrl_jax" and _floor(t) > _floor(m)]
    assert not up, up


def test_every_moved_module_name_says_where_it_lives_now():
    import importlib

    import pytest

    from docrl_jax.moved import MOVED_MODULES, MovedModuleError
    for old, new in MOVED_MODULES.items():
        with pytest.raises(MovedModuleError, match=f"{old} moved: import {new.split()[0]}"):
            importlib.import_module(old)
        parent, _, leaf = old.rpartition(".")
        with pytest.raises(MovedModuleError, match=f"{old} moved"):   # the `from package import old` form
            exec(f"from {parent} import {leaf}", {})
    with pytest.raises(ImportError, match="RunDirError moved: import it from docrl_jax.errors"):
        exec("from docrl_jax.policy import RunDirError", {})
    with pytest.raises(ImportError, match="import plan from docrl_jax.train.sweep"):
        exec("from docrl_jax.sweep import plan", {})


def test_scripts_compile():
    """Every script beside the package (benchmarks, examples) is valid Python: they run only on a GPU
    machine or by hand, so nothing else here would notice one broken by an edit."""
    root = PKG.parent
    bad = []
    for path in sorted([*root.glob("benchmarks/*.py"), *root.glob("examples/**/*.py")]):
        try:
            compile(path.read_text(), str(path), "exec")
        except SyntaxError as e:
            bad.append(f"{path.relative_to(root)}:{e.lineno}: {e.msg}")
    assert not bad, bad


def test_the_train_command_reads_its_config_before_the_heavy_imports():
    """`python -m docrl_jax.train` resolves its config and starts loading the stored programs
    (docrl_jax.train.program_store.prefetch) before MJX, Orbax and Optax are imported, so that the
    loads overlap those imports: the command line, the config and the store must not pull them in."""
    code = ("import sys, docrl_jax.train.cli, docrl_jax.train.program_store, docrl_jax.config as c; "
            "c.load_config('td3_lstm', ['env.num_envs=8']); "
            "print(sorted(m for m in ('mujoco.mjx', 'orbax.checkpoint', 'optax') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_tests_mirror_the_package_and_no_test_imports_another():
    import re
    root = Path(__file__).resolve().parent
    package = root.parent / "docrl_jax"
    folders = {p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))} - {"data"}
    # every folder of tests/ is a subpackage's, or the benchmark scripts'
    assert folders <= {p.name for p in package.iterdir() if (p / "__init__.py").is_file()} | {"benchmarks"}, folders
    for path in root.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"^\s*(from (tests\.)?test_\w+ import|import (tests\.)?test_\w+)", text, re.M), path


def test_no_module_is_longer_than_400_lines():
    root = Path(__file__).resolve().parent.parent / "docrl_jax"
    long = {str(p.relative_to(root)): n for p in root.rglob("*.py") if (n := len(p.read_text().splitlines())) > 400}
    assert not long, long
