"""`python -m docrl_jax.compare`: several evaluation outputs in one Table I beside the paper's rows."""

from __future__ import annotations

import json

import pytest

from docrl_jax import evaluate
from docrl_jax.evaluate import compare


def _row(method, seed, scenario, direction, successes, t_air=10.0, t_water=5.0, trials=100):
    n = successes
    return {"method": method, "seed_index": seed, "scenario": scenario, "direction": direction, "trials": trials,
            "successes": n, "success_rate": n / trials, "collisions": trials - n, "out_of_bounds": 0, "timeouts": 0,
            "diverged": 0, "t_air_mean": t_air if n else float("nan"), "t_air_std": 1.0 if n else float("nan"),
            "t_water_mean": t_water if n else float("nan"), "t_water_std": 0.5 if n else float("nan"),
            "time_mean": t_air + t_water, "time_std": 1.0, "path_length_mean": 8.0, "path_length_std": 0.1}


def _write(out, rows, seeds=True):
    evaluate.write_outputs(out, rows, [], {"command": "test"}, evaluate.aggregate_seeds(rows) if seeds else [])
    return out


def test_side_by_side_table(tmp_path):
    learned = [_row("DoCRL-D", s, sc, d, n) for s, n in ((0, 90), (1, 100), (2, 95))
               for sc in (1, 2) for d in ("air_to_water", "water_to_air")]
    bba = [_row("BBA", None, sc, d, 0 if d == "water_to_air" else 34) for sc in (1, 2)
           for d in ("air_to_water", "water_to_air")]
    a = _write(tmp_path / "d", learned)
    b = _write(tmp_path / "bba", bba, seeds=False)
    aggs = compare.load_eval(b) + compare.load_eval(a)
    text = compare.side_by_side_markdown(aggs)
    lines = text.splitlines()
    aw_d = next(line for line in lines if line.startswith("| A-W DoCRL-D | 95.0"))
    # ours: mean 95, population std over (90, 100, 95) = 4.08; paper: 100, 14.55 ± 0.87, 11.19 ± 2.86
    assert "95.0 ± 4.1 of 100 [90, 100, 95]" in aw_d and "| 100 of 100 | 14.55 ± 0.87 | 11.19 ± 2.86 |" in aw_d
    wa_bba = next(line for line in lines if line.startswith("| W-A BBA |"))
    assert "| 0 of 100 | – | – |" in wa_bba and "| 32 of 100 | 38.01 ± 29.83 | 3.79 ± 0.27 |" in wa_bba
    # paper order within a direction (DoCRL-D before BBA), A-W before W-A
    assert lines.index(aw_d) < next(i for i, l in enumerate(lines) if l.startswith("| A-W BBA |"))
    assert "| A-W DoCRL-D | 95.0 ± 4.1 of 100 (10.0 / 5.0) | 95.0 ± 4.1 of 100 (10.0 / 5.0) |" in text


def test_cli_writes_file_and_rejects_bad_input(tmp_path, capsys):
    a = _write(tmp_path / "d", [_row("DoCRL-D", 0, 2, "air_to_water", 50)])
    out = tmp_path / "t.md"
    assert compare.main([str(a), "--out", str(out)]) == 0
    assert "| A-W DoCRL-D | 50 of 100 |" in out.read_text()
    with pytest.raises(SystemExit):
        compare.main([str(tmp_path / "missing")])
    assert "does not exist" in capsys.readouterr().err
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "results.json").write_text(json.dumps({"meta": {}}))
    with pytest.raises(SystemExit):
        compare.main([str(tmp_path / "bad")])
    assert "not an evaluation results.json" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        compare.main([str(a), str(a)])
    assert "distinct --label" in capsys.readouterr().err


def test_counts_are_out_of_the_trials_run(tmp_path, capsys):
    """An evaluation of 10 trials is reported out of 10, beside the paper's count out of 100."""
    d = tmp_path / "bba10"
    d.mkdir()
    rows = [_row("BBA", None, 2, "air_to_water", 4, trials=10), _row("BBA", None, 2, "water_to_air", 0, trials=10)]
    (d / "results.json").write_text(json.dumps({"meta": {"trials": 10}, "results": rows}))  # as written by hand
    assert compare.main([str(d)]) == 0
    text = capsys.readouterr().out
    assert "out of 100" not in text
    aw = next(line for line in text.splitlines() if line.startswith("| A-W BBA |"))
    assert "| 4 of 10 |" in aw and "| 11 of 100 |" in aw
    assert "| A-W BBA | 4 of 10 (" in text.split("Every scenario")[1]


@pytest.mark.parametrize("variant", ["defaults_2026_11_24"])
def test_committed_tables_regenerate(variant):
    """docs/results/*/table_i.md is exactly what compare makes of the committed evaluation outputs."""
    from pathlib import Path
    docs = Path(__file__).resolve().parents[2] / "docs" / "results"
    dirs = [docs / variant / m for m in ("td3", "sac", "sto", "det")] + [docs / "bba"]
    aggs = [a for d in dirs for a in compare.load_eval(d)]
    assert {a["method"] for a in aggs} == {"DoCRL-D", "DoCRL-S", "Sto.", "Det.", "BBA"}
    assert all(len(a["successes_per_seed"]) == (1 if a["method"] == "BBA" else 3) for a in aggs)
    assert compare.side_by_side_markdown(aggs) == (docs / variant / "table_i.md").read_text()
