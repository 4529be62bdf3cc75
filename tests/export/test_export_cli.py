"""`python -m docrl_jax.export`: the manifest, and every bad input refused in one line with exit
status 2 before anything is converted; the package imports without the optional ONNX packages."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from docrl_jax.export import cli
from docrl_jax.export.artefacts import EXPORT_FILES, ONNX_FILE

ROOT = Path(__file__).resolve().parents[2]
TD3 = ROOT / "tests" / "data" / "trained" / "td3_lstm"
ONNX_PACKAGES = ("jax2onnx", "onnx", "onnxruntime")


def _refused(capsys, argv) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("python -m docrl_jax.export: error: "), err
    return err[0]


def test_bad_runs_are_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    assert "does not exist" in _refused(capsys, ["--run", str(tmp_path / "nope"), "--out", str(out)])
    assert "num_seeds=1" in _refused(capsys, ["--run", str(TD3), "--seed-index", "1", "--out", str(out)])
    assert "must be >= 0" in _refused(capsys, ["--run", str(TD3), "--seed-index", "-1", "--out", str(out)])
    no_best = tmp_path / "no_best"
    shutil.copytree(TD3, no_best)
    for best in no_best.glob("checkpoints/*/best"):
        shutil.rmtree(best)
    assert "holds no best policy" in _refused(capsys, ["--run", str(no_best), "--which", "best", "--out", str(out)])
    assert "valid formats are onnx, stablehlo, numpy" in _refused(
        capsys, ["--run", str(TD3), "--formats", "onnx,tflite", "--out", str(out)])
    assert not out.exists()   # nothing was written for a refused command


def test_an_unwritable_out_is_one_line(tmp_path, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    assert "a_file/x" in _refused(capsys, ["--run", str(TD3), "--out", str(blocker / "x")])
    assert "is a file" in _refused(capsys, ["--run", str(TD3), "--out", str(blocker)])


def test_the_manifest_and_an_existing_export(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["--run", str(TD3), "--out", str(out)]) == 0   # the run's policy: it kept a best one
    printed = capsys.readouterr().out
    assert "best policy of seed index 0" in printed and "onnx: policy.onnx" in printed
    manifest = json.loads((out / "policy.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == sorted(EXPORT_FILES)
    assert manifest["policy"] == {"config": "td3_lstm", "algo": "td3", "actor": "lstm", "hidden": [32], "units": 32,
                                  "recurrent": True, "network": manifest["policy"]["network"]}
    assert manifest["control_period_s"] == 0.2 and manifest["observation"]["size"] == 26
    layout = {entry["name"]: entry for entry in manifest["observation"]["layout"]}
    assert layout["ranges"]["index"] == [0, 19] and layout["goal_distance"]["index"] == 25
    assert layout["ranges"]["lidar"]["bearings_deg"][0] == -135.0 and layout["ranges"]["sonar"]["max_range_m"] == 20.0
    assert manifest["carry"]["names"] == ["c", "h"] and manifest["carry"]["initial_value"] == 0.0
    assert manifest["files"]["onnx"]["inputs"] == ["observation", "c", "h"]
    assert manifest["source"]["which"] == "best" and manifest["source"]["checkpoint_env_steps"] == 50380800
    assert all(isinstance(d, float) and d <= 1e-5 for d in manifest["check"]["max_abs_action_diff"].values())
    assert {"jax", "jax2onnx", "onnx", "onnxruntime"} <= {k for k, v in manifest["versions"].items() if v}

    assert "already holds an export" in _refused(capsys, ["--run", str(TD3), "--out", str(out)])
    # --force replaces it, and no file of the old export is left behind
    assert cli.main(["--run", str(TD3), "--which", "final", "--out", str(out), "--formats", "numpy", "--force"]) == 0
    assert not (out / ONNX_FILE).exists()
    assert json.loads((out / "policy.json").read_text())["source"]["which"] == "final"


def test_onnx_without_its_packages_names_the_extra(tmp_path, capsys, monkeypatch):
    for name in ONNX_PACKAGES:
        monkeypatch.setitem(sys.modules, name, None)   # `import name` raises ImportError
    line = _refused(capsys, ["--run", str(TD3), "--out", str(tmp_path / "out")])
    assert "pip install -e '.[export]'" in line and "jax2onnx" in line
    assert cli.main(["--run", str(TD3), "--out", str(tmp_path / "out"), "--formats", "stablehlo,numpy"]) == 0


def test_the_command_and_the_package_without_onnx():
    """`python -m docrl_jax.export` answers bad input in one line; the package, the export command and
    the other commands import with jax2onnx, onnx and onnxruntime missing."""
    blocked = f"import sys; sys.modules.update(dict.fromkeys({list(ONNX_PACKAGES)!r}));"
    imports = "import docrl_jax.export, docrl_jax.export.cli, docrl_jax.export.runners, docrl_jax.evaluate.cli"
    proc = subprocess.run([sys.executable, "-c", blocked + imports], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    proc = subprocess.run([sys.executable, "-m", "docrl_jax.export", "--run", "/nonexistent", "--out", "/tmp/x"],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 2 and proc.stderr.strip().splitlines() == [
        "python -m docrl_jax.export: error: run directory '/nonexistent' does not exist"]


@pytest.mark.parametrize("argv", [["--out", "x"], ["--run", "x"]])
def test_run_and_out_are_required(argv, capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(argv)
    assert e.value.code == 2
