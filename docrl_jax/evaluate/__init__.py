"""Evaluation of trained and built-in policies under the paper's protocol, in one package.

    protocol       what a trial is: env settings, directions, nominal yaws, start jitter (shared with the trainer)
    rollout        the evaluator's vmapped rollout, per-trial metrics, `evaluate_policy` (the whole protocol)
    tables         summaries, statistics over seeds, Markdown tables, results.{md,csv,json}, trials.csv
    cli            `python -m docrl_jax.evaluate`
    compare        `python -m docrl_jax.compare`: several evaluations beside the paper's Table I
    paper_results  the paper's published Table I
    plotting       trajectory figures and Figure 3 (`python -m docrl_jax.plotting`)
    curves         learning curves from metrics.csv
    video          the trials drawn by MuJoCo's renderer to MP4 or GIF (`python -m docrl_jax.render`)
    robustness     beyond the protocol: perturbation sweeps, random trips, held-out procedural layouts
    robustness_cli     `python -m docrl_jax.robustness`
    robustness_report  its robustness.{csv,json,md,png}, the median over seeds

The package's names below are imported from protocol, rollout and tables when first used, so that
`python -m docrl_jax.evaluate --help` (which imports this package first) answers before JAX is imported.
"""

from docrl_jax.moved import lazy_members

__getattr__ = lazy_members(__name__, {
    **{name: "docrl_jax.evaluate.protocol" for name in ("DEFAULT_EVAL_ENV", "DIRECTIONS", "NOMINAL_YAW", "OUTCOMES",
                                                       "SCENARIOS", "TrialSpec", "trial_starts")},
    **{name: "docrl_jax.evaluate.rollout" for name in ("evaluate_policy", "make_eval_env", "make_rollout",
                                                      "run_trials", "trial_metrics")},
    **{name: "docrl_jax.evaluate.tables" for name in ("SHORT", "aggregate_seeds", "markdown_table", "mean_std",
                                                     "plus_minus", "summarize", "trial_table", "write_outputs")}})


def main(argv=None) -> int:
    """`python -m docrl_jax.evaluate` (docrl_jax.evaluate.cli.main), imported on call."""
    from docrl_jax.evaluate.cli import main as cli_main
    return cli_main(argv)


__all__ = ["DEFAULT_EVAL_ENV", "DIRECTIONS", "NOMINAL_YAW", "OUTCOMES", "SCENARIOS", "SHORT", "TrialSpec",
           "aggregate_seeds", "evaluate_policy", "main", "make_eval_env", "make_rollout", "markdown_table",
           "mean_std", "plus_minus", "run_trials", "summarize", "trial_metrics", "trial_starts", "trial_table",
           "write_outputs"]
