"""A run's policy (docrl_jax.runs.load_policy's default, every command's --which default): the seed's best
evaluated policy where the checkpoint keeps one, else its final policy; explicit choices load what they name;
labels, the evaluator's results.json and the export manifest say which was loaded. On the trained td3_lstm run
of tests/data (it kept a best policy) and a copy of it as a train.track_best_policy false run writes it (no
best item): loads and argument checks only, nothing compiles a rollout."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import jax
import numpy as np
import pytest

from docrl_jax import checkpoint, runs
from docrl_jax.errors import RunDirError
from docrl_jax.evaluate import cli, cli_run, policies, robustness_cli, video
from docrl_jax.export import cli as export_cli
from docrl_jax.policy import RUN_POLICY_RULE

TRAINED = Path(__file__).resolve().parents[1] / "data" / "trained" / "td3_lstm"


@pytest.fixture(scope="module")
def no_best(tmp_path_factory):
    """The trained run as train.track_best_policy false leaves it: the config says so, no checkpoint has `best/`."""
    d = tmp_path_factory.mktemp("runs") / "no_best"
    shutil.copytree(TRAINED, d)
    for best in d.glob("checkpoints/*/best"):
        shutil.rmtree(best)
    config = (d / "config.yaml").read_text()
    assert "track_best_policy: true" in config
    (d / "config.yaml").write_text(config.replace("track_best_policy: true", "track_best_policy: false"))
    return d


def _stacked(run_dir, item):
    """(actors stacked over seeds as the checkpoint stores `item`: "policy" the final ones, "best"; its meta),
    read without load_policy."""
    from docrl_jax.algorithms import make_agent
    config = runs.read_config(run_dir)
    _, stacked, meta = checkpoint.restore(checkpoint.manager(run_dir), checkpoint.latest_step(run_dir),
                                          abstract_policy=runs.policy_abstract(make_agent(config), config), item=item)
    return jax.tree.map(np.asarray, stacked), meta


def _stored(run_dir, item):
    return jax.tree.map(lambda x: x[0], _stacked(run_dir, item)[0])


@pytest.fixture(scope="module")
def kept_apart(tmp_path_factory):
    """The trained run with a later checkpoint whose best policy is not its final one (the trained run's last
    evaluation was its best: there they are the same): final as stored, best = final + 0.5 in every weight."""
    d = tmp_path_factory.mktemp("runs") / "td3_lstm"
    shutil.copytree(TRAINED, d)
    final, meta = _stacked(d, "policy")
    step = checkpoint.latest_step(d) + 1
    checkpoint.save(checkpoint.manager(d), step, {"unused": np.zeros(1)}, final, meta,
                    best_params=jax.tree.map(lambda x: x + 0.5, final))
    return d


def _same(a, b) -> bool:
    return all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def test_the_default_is_the_best_policy_where_kept_else_the_final_one(kept_apart, no_best):
    best, final = _stored(kept_apart, "best"), _stored(kept_apart, "policy")
    assert not _same(best, final)   # else nothing here could tell the two apart
    default = runs.load_policy(kept_apart)
    assert default.which == "best" and default.source.startswith("best policy of seed index 0")
    assert default.source.endswith("kept in checkpoint 50380801") and _same(default.params, best)
    assert runs.checkpoint_policy(kept_apart) == "best" and runs.checkpoint_policy(no_best) == "final"
    fallback = runs.load_policy(no_best)
    assert fallback.which == "final" and fallback.source == "final policy of seed index 0: checkpoint 50380800"
    assert _same(fallback.params, _stored(no_best, "policy"))


def test_explicit_choices_load_what_they_name(kept_apart, no_best):
    explicit_final = runs.load_policy(kept_apart, which="final")
    assert explicit_final.which == "final" and _same(explicit_final.params, _stored(kept_apart, "policy"))
    explicit_best = runs.load_policy(kept_apart, which="best")
    assert explicit_best.which == "best" and _same(explicit_best.params, _stored(kept_apart, "best"))
    assert runs.checkpoint_policy(no_best, "best") == "best"   # asked for: the load then says it is missing
    with pytest.raises(RunDirError, match="holds no best policy.*which='final'"):
        runs.load_policy(no_best, which="best")
    for bad in (lambda: runs.load_policy(TRAINED, which="newest"), lambda: runs.checkpoint_policy(TRAINED, "newest")):
        with pytest.raises(RunDirError, match="valid choices are final, best, or None for the run's policy"):
            bad()
    with pytest.raises(RunDirError, match="has no checkpoint"):
        runs.checkpoint_policy(TRAINED.parent)


def test_every_command_defaults_to_the_rule():
    for parser, argv in ((cli.build_parser(), ["--run", "r"]), (robustness_cli.build_parser(), ["--run", "r"]),
                         (video.build_parser(), ["--run", "r"]), (export_cli.build_parser(), ["--run", "r", "--out", "o"])):
        assert parser.parse_args(argv).which is None, parser.prog
        assert parser.parse_args([*argv, "--which", "final"]).which == "final"
        (action,) = [a for a in parser._actions if a.dest == "which"]
        assert action.choices == ("final", "best") and RUN_POLICY_RULE in action.help, parser.prog


def test_labels_say_what_was_loaded(no_best, tmp_path):
    args = cli.build_parser().parse_args(["--run", str(TRAINED)])
    policy, label = cli_run.load_policy_for(args, None, 0, str(TRAINED))
    assert (policy.which, label) == ("best", "td3_lstm (best)")
    args = cli.build_parser().parse_args(["--run", str(TRAINED), "--which", "final"])
    assert cli_run.load_policy_for(args, None, 0, str(TRAINED))[1] == "td3_lstm"
    args = cli.build_parser().parse_args(["--run", str(no_best)])
    assert cli_run.load_policy_for(args, None, 0, str(no_best))[1] == "no_best"
    assert policies.policy_for(None, str(TRAINED))[1] == "td3_lstm (best)"   # render's label
    assert policies.policy_for(None, str(no_best))[1] == "no_best"

    def methods(*argv):
        parsed = robustness_cli.build_parser().parse_args(   # the cheapest test to check the settings of
            [*argv, "--tests", "random_trips", "--perturbations", "none", "--out", str(tmp_path / "o")])
        cfg = robustness_cli.validate_args(parsed)
        return [m.label for m in cfg["methods"]], robustness_cli.metadata(parsed, cfg, [], 0.0)["which"]

    assert methods("--run", str(TRAINED), "--run", str(no_best)) == (
        ["td3_lstm (best)", "no_best"], {"td3_lstm (best)": "best", "no_best": "final"})
    assert methods("--run", str(TRAINED), "--which", "final") == (["td3_lstm"], {"td3_lstm": "final"})
    # one method's seeds are all best or all final policies
    with pytest.raises(robustness_cli.UsageError, match="keep different policies .*td3_lstm best, no_best final"):
        methods("--run", str(TRAINED), str(no_best))
    assert methods("--run", str(TRAINED), str(no_best), "--which", "final")[0] == ["td3_lstm"]


def test_the_export_manifest_says_what_was_loaded(no_best, tmp_path, capsys):
    out = tmp_path / "e"
    assert export_cli.main(["--run", str(no_best), "--formats", "numpy", "--out", str(out)]) == 0
    source = json.loads((out / "policy.json").read_text())["source"]
    assert source["which"] == "final" and source["policy"].startswith("final policy of seed index 0")
    # a shipped policy is one seed's final policy: --which is refused beside it, whichever is asked
    for which in ("final", "best"):
        assert export_cli.main(["--policy", "td3_lstm", "--which", which, "--out", str(tmp_path / "p")]) == 2
        assert "one seed's final policy" in capsys.readouterr().err
