"""The best policy of each seed so far, tracked beside the run's final policy (`train.track_best_policy`).

After every periodic evaluation, each seed's evaluated policy (the Polyak average, as the final
policy) is compared with that seed's best so far by its score: with `train.eval_paper_pairs` the lower
of the air-to-water and water-to-air success (the target is both directions), without them the
random-goal success. A policy at least as good as the best replaces it, so ties go to the later,
longer-trained policy. The random-goal success is no tie-break beside the pairs: once the pairs read
100 / 100 it differs between evaluations by a few episodes of 100, and as a tie-break it picked an
earlier policy than the latest of the same pair score in 13 of 16 seeds of td3_lstm (one from 7.7 M
of 25.4 M env steps, which flew scenario 3 W-A at 38 % where the final flew 100;
benchmarks/results/h200x4/final_policies/).
The best is kept on the host (a few kilobytes per seed) and written into every checkpoint as its
`best` item, beside `policy` (the final/current one), with this bookkeeping in the checkpoint's meta;
a resume restores both, so an interrupted run picks the same best as an uninterrupted one.

The best is chosen on the very evaluation episodes it is scored on, so its training-time score is
optimistic: the evaluator (`python -m docrl_jax.evaluate --run RUN`, which loads it by default, where kept)
flies it on other episodes, and those are the figures to quote.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jax
import numpy as np

PAIR_KEYS = ("success_air_to_water", "success_water_to_air")


@dataclass(frozen=True)
class BestPolicy:
    params: Any               # host (numpy) actor params stacked over seeds; each seed's slice is its best
    score: np.ndarray         # (num_seeds,): the score of each seed's best
    env_steps: np.ndarray     # (num_seeds,): the evaluation each best comes from
    evaluation: list[dict]    # per seed: the evaluation's success fractions, for the record


def score(ev: dict) -> np.ndarray:
    """(num_seeds,) scores of one evaluation (`ev`: per-seed arrays, as the evaluate program returns)."""
    if PAIR_KEYS[0] in ev:
        return np.minimum(*(np.asarray(ev[k], np.float64) for k in PAIR_KEYS))
    return np.asarray(ev["success_rate"], np.float64)


def update(best: BestPolicy | None, params: Any, ev: dict, env_steps: int) -> tuple[BestPolicy, np.ndarray]:
    """The best after an evaluation of `params` (host arrays stacked over seeds) at `env_steps`, and
    which seeds it replaced. The first evaluation always sets the best."""
    new = score(ev)
    summary = [{k: float(np.asarray(ev[k])[i]) for k in ("success_rate", *PAIR_KEYS) if k in ev}
               for i in range(len(new))]
    if best is None:
        return BestPolicy(params, new, np.full(len(new), env_steps, np.int64), summary), np.ones(len(new), bool)
    better = new >= best.score
    pick = lambda n, o: np.where(better.reshape((-1,) + (1,) * (np.ndim(n) - 1)), n, o)  # noqa: E731
    return BestPolicy(jax.tree.map(pick, params, best.params), np.where(better, new, best.score),
                      np.where(better, env_steps, best.env_steps),
                      [s if b else o for s, b, o in zip(summary, better, best.evaluation)]), better


def to_meta(best: BestPolicy) -> dict:
    """JSON for the checkpoint's meta (the params go into its `best` item)."""
    return {"score": best.score.tolist(), "env_steps": best.env_steps.tolist(), "evaluation": best.evaluation}


def from_meta(params: Any, meta: dict) -> BestPolicy:
    score = np.asarray(meta["score"], np.float64)
    if score.ndim == 2:  # written when the random-goal success broke ties: (today's score, the tie-break)
        score = score[:, 0]
    return BestPolicy(params, score, np.asarray(meta["env_steps"], np.int64), list(meta["evaluation"]))
