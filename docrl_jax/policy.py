"""The acting contract shared by learned agents and baselines, used by the evaluator.

A `Policy` is data plus pure functions, so a whole batch of evaluation trials runs as one
`jit(vmap(scan))`:

    carry = policy.init_carry()                                   # one env's memory (pytree)
    carry, action = policy.act(policy.params, carry, obs, info, key)

`obs` is the env's 26-float observation, `info` the env's info dict of the same step (a classical
baseline such as BBA reads pose and ranges from it, as the original read odometry; learned policies
ignore it), `key` a PRNG key (deterministic policies ignore it). `action` is in [-1, 1]^3. The
carry is reset to `init_carry()` at the start of every trial. A policy that plans over each trial's tank
sets `trial_params` (below): the rollout then gives every trial its own params.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

from docrl_jax.moved import moved_names


# Which policy of a run's checkpoint to load, when asked explicitly: the final one (the Polyak-averaged actor at
# the checkpoint), or each seed's best evaluated one (docrl_jax.train.best_policy). Asking for neither (None)
# loads the run's policy, runs.checkpoint_policy's rule; every --which offers these and says that rule.
CHECKPOINT_POLICIES = ("final", "best")
RUN_POLICY_RULE = "best where the run kept one (train.track_best_policy), else final"


@dataclass(frozen=True)
class Policy:
    name: str
    params: Any
    init_carry: Callable[[], Any]
    act: Callable[[Any, Any, Any, dict, Any], tuple[Any, Any]]
    source: str = ""   # where the params came from (load_policy: final or best, which checkpoint)
    which: str = ""    # load_policy: the checkpoint's policy it loaded, "final" or "best"; "" for any other policy
    # A policy that knows each trial's tank (docrl_jax.baselines.route: the route-follower, a route-guided policy):
    # trial_params(params, env, initial states) -> its params for each trial, mapped over the trials of a
    # rollout with vmap in_axes `trial_axes` (e.g. a route plan per trial, the network's params shared). None:
    # `params` serve every trial.
    trial_params: Callable[[Any, Any, Any], Any] | None = None
    trial_axes: Any = None


moved_names(__name__, {"RunDirError": "docrl_jax.errors"})
