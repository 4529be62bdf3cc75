"""A tank set as the evaluation's trials see it (docrl_jax/evaluate/tank_trials.py says which trials): its
names and stacked layouts, each trial's tank, and a tank's subset of the trials. Below both the tank
trials and the robustness benchmark, which use it.
"""

from __future__ import annotations

import numpy as np

TEST = "tanks"          # the trip-key salt's name (rollout.TRIP_SALT), shared with the benchmark's test
ALL = "all"             # the tank column of a row over the whole set


class TankSetError(ValueError):
    """A bad --tank: the tank set's own one-line error (`tanks.TankError`); the commands print it without
    their usage block."""


def check(spec: str, params, flag: str = "--tank") -> list[str]:
    """The names of the tank set `spec`, loaded for `params` as the trials will load it (every rule of
    docs/TANKS.md checked, before anything compiles); TankSetError with the set's one line after the
    flag that gave it ('--tank /x/picture.gif: not a text file; ...': the file, then the problem). Every
    command checks its tank set here."""
    from docrl_jax.envs.tanks import TankError
    try:
        return load(spec, params)[0]
    except TankError as e:
        raise TankSetError(f"{flag} {e}") from None


def load(spec: str, params) -> tuple[list[str], object]:
    """(names, layouts stacked over the set) of a tank file, a folder of them, a packaged tank's name or
    "gallery", for the env parameters `params` (scenario 0; `tanks.load_set` caches it). Raises
    `tanks.TankError` (one line). Tanks that share a name are told apart by their file's name."""
    from docrl_jax.envs import tanks
    names = list(tanks.names(spec))
    files = tanks.files(spec)
    names = [f"{n} ({f.name})" if names.count(n) > 1 else n for n, f in zip(names, files)]
    return names, tanks.load_set(spec, params)


def tank_index(num_trials: int, num_tanks: int) -> np.ndarray:
    """The tank of each trial: trial i flies in tank i mod K."""
    return np.arange(num_trials) % num_tanks


def spread(num_tanks: int, count: int) -> np.ndarray:
    """`count` tanks of a set of `num_tanks` spread evenly over it, first and last included (all of them
    when count >= num_tanks): the sample a short run flies rather than the set's first tanks."""
    if count >= num_tanks:
        return np.arange(num_tanks)
    return np.unique(np.round(np.linspace(0, num_tanks - 1, count)).astype(int))


def pick(names: list[str], stack, sample: np.ndarray | None):
    """(names, stack) of the tanks at `sample` (None: the whole set)."""
    if sample is None:
        return names, stack
    import jax
    idx = np.asarray(sample)
    return [names[i] for i in idx], jax.tree.map(lambda x: x[idx], stack)


def repeat(stack, num_trials: int):
    """The set's stacked layouts repeated to one per trial (`tank_index`)."""
    import jax
    num_tanks = int(np.shape(stack.index)[0])
    idx = tank_index(num_trials, num_tanks)
    return jax.tree.map(lambda x: x[idx], stack)


def subset(trials: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, np.ndarray]:
    """The per-trial arrays of `trials` (leading axis N) at `mask`."""
    return {k: v[mask] for k, v in trials.items() if np.ndim(v) and len(v) == len(mask)}
