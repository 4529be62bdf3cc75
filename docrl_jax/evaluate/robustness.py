"""The robustness benchmark (`python -m docrl_jax.robustness`, the command: `robustness_cli`): how
a policy's success holds up off the paper's nominal trials. Three tests, each counting successes,
collisions, out-of-bounds and time-outs per scenario and direction (A-W, W-A):

  perturbations     the paper's pairs with the evaluator's very trials (`rollout.trial_key`,
                    `trial_starts`, `DEFAULT_EVAL_ENV`) in scenarios 1-3, under each perturbation of
                    `ENVELOPE` at each of its magnitudes; the nominal row (no perturbation) once.
  random_trips      starts, goals and headings of the env's own reset distribution in scenarios 1-3,
                    the media forced per direction (A-W: start in air, goal under water; W-A the
                    reverse); trial i's key depends on (seed, scenario, direction, i) only.
  held_out_layouts  scenario 0: held-out procedural layout i (`layouts.held_out(i)`, never trained
                    on) for i < N, one A-W and one W-A trip in each (random start, goal, yaw).
  structured        scenario 0: the first N flyable held-out structured layouts (walls with one
                    opening, ceilings, rooms, dead ends, groves: `structures.held_out_set(N)`), one
                    trip each way in each, their starts and goals in each layout's regions.
  tanks             a tank set (`--tank`, default the packaged gallery; docs/TANKS.md): trip i of each
                    direction in tank i mod the set's size, from its region of the start medium to
                    its region of the other (`tank_trials`: the trials of `evaluate --tank`); a row
                    per direction over the set (tank "all") and one per tank flown.

All trials of one (env settings, direction) are one `jit(vmap(scan))` of the evaluator's rollout. A
perturbation changes the episode's plant only (`dr_*` parameters: the true vehicle, water, wind,
sensors, delays), which the rollout takes as data (`rollout.run_trials(..., plants_of=...)`): every
perturbation of a scenario runs in one compiled program, that of a "host" env whose structure admits
them all (latency queues as long as the longest delay; dropouts and range noise drawn), and its
trials are, bit for bit, those of an env built with the perturbation's overrides. The trips start
from `env.reset(key, layout=...)` of the host env with the media forced (`rollout.reset_states`) and
run in the same program, with the nominal plant and the policy's own vehicle; the layout tests share
scenario 0's program.

`run_benchmark(methods, cfg)` runs it all and returns one row per (method, seed, test, perturbation,
magnitude, scenario, direction, tank); `robustness_report` writes the files.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from docrl_jax.evaluate import policies, rollout
# The trips' media, keys and runner live in rollout, where the tank trials fly them too.
from docrl_jax.evaluate.rollout import MEDIA, trip_keys, trip_trials
from docrl_jax.evaluate.protocol import NOMINAL_YAW
from docrl_jax.evaluate.robustness_report import NOMINAL, NONE
from docrl_jax.evaluate.tables import SHORT, summarize


@dataclass(frozen=True)
class Perturbation:
    """One perturbation of the envelope: env parameter `param` fixed at each magnitude, i.e. the
    range (v, v) (a scale multiplies the nominal value; `nominal` is the unperturbed value)."""
    name: str
    title: str
    param: str
    unit: str                        # "x": a scale of the nominal value; otherwise the magnitude's unit
    nominal: float
    magnitudes: tuple[float, ...]
    doc: str

    def overrides(self, value: float) -> dict[str, tuple]:
        v = int(value) if self.unit == "steps" else float(value)
        return {self.param: (v, v)}

    def label(self, value: float) -> str:
        if self.unit == "x":
            return f"x{value:g}"
        if self.unit == "p":
            return f"p={value:g}"
        return f"{value:g} {self.unit[:-1] if self.unit == 'steps' and value == 1 else self.unit}"


# The default envelope: name -> env overrides per magnitude (`Perturbation.overrides`: param = (v, v)).
ENVELOPE = (
    Perturbation("wind_gusts", "Wind gusts", "dr_wind_scale", "x", 1.0, (1.5, 2.0, 3.0, 4.0),
                 "the air's Ornstein-Uhlenbeck wind noise (and so its stationary std) x magnitude"),
    Perturbation("water_current", "Water current", "dr_current_speed", "m/s", 0.0, (0.1, 0.25, 0.5),
                 "a constant current of this speed, its direction uniform in 3-D, drawn per trial"),
    Perturbation("motor_lag", "Motor lag", "dr_motor_tau_scale", "x", 1.0, (2.0, 5.0, 10.0),
                 "rotor thrust time constants x magnitude"),
    Perturbation("action_latency", "Action latency", "dr_action_latency", "steps", 0, (1, 2),
                 "the controller acts on the action of this many control steps (0.2 s each) ago"),
    Perturbation("obs_latency", "Observation latency", "dr_obs_latency", "steps", 0, (1, 2),
                 "the agent sees the observation of this many control steps ago"),
    Perturbation("beam_dropout", "Beam dropouts", "dr_beam_dropout", "p", 0.0, (0.05, 0.1, 0.2),
                 "each beam reads the sensor's maximum range with this probability per step"),
    Perturbation("range_noise", "Extra range noise", "dr_range_noise_std", "m", 0.0, (0.05, 0.1),
                 "std of Gaussian range noise added to the evaluation's 0.01 m"),
    Perturbation("buoyancy", "Buoyancy", "dr_hull_volume_scale", "x", 1.0, (0.0, 4.0),
                 "displaced volume x magnitude (x0: no buoyancy; nominal 2.5 % of the weight)"),
    Perturbation("mass", "Mass", "dr_mass_scale", "x", 1.0, (0.8, 1.2), "vehicle mass and inertia x magnitude"),
    Perturbation("water_drag", "Water drag", "dr_water_drag_scale", "x", 1.0, (0.5, 2.0),
                 "every water drag coefficient x magnitude"),
    Perturbation("thrust_water", "Thrust in water", "dr_thrust_water_scale", "x", 1.0, (0.5,),
                 "rotor thrust limit under water x magnitude"),
    Perturbation("thrust_air", "Thrust in air", "dr_thrust_air_scale", "x", 1.0, (0.7,),
                 "rotor thrust limit in air x magnitude"),
    Perturbation("added_mass", "Added mass", "dr_added_mass_scale", "x", 1.0, (0.5, 2.0),
                 "added mass and added inertia in water x magnitude"),
)
PERTURBATIONS = {p.name: p for p in ENVELOPE}
TESTS = ("perturbations", "random_trips", "held_out_layouts", "structured", "tanks")
LAYOUT_TESTS = ("held_out_layouts", "structured", "tanks")   # scenario 0, a layout given per trip


@dataclass(frozen=True)
class Setting:
    """One sweep row's env: a perturbation at one magnitude, or the nominal (no perturbation)."""
    perturbation: str
    magnitude: str
    value: float | None
    overrides: dict = field(default_factory=dict)


def sweep_settings(names: Sequence[str], quick: bool = False) -> list[Setting]:
    """The nominal setting, then every magnitude of each named perturbation (`quick`: its strongest,
    the one furthest from nominal)."""
    out = [Setting(NOMINAL, "", None)]
    for name in names:
        p = PERTURBATIONS[name]
        values = (max(p.magnitudes, key=lambda v: abs(v - p.nominal)),) if quick else p.magnitudes
        out += [Setting(name, p.label(v), float(v), p.overrides(v)) for v in values]
    return out


def host_overrides(base: dict, settings: Sequence[Setting]) -> dict:
    """The host env's overrides: `base` plus, for every `dr_*` parameter any setting fixes, the range
    spanning its base value and all of theirs (the host's own draws are never used: every trial gets
    its plant; the spans only size the latency queues and switch on the noise and dropout draws)."""
    from docrl_jax.envs.params import EnvParams
    defaults = EnvParams()
    host = dict(base)
    for s in settings:
        for k, (lo, hi) in s.overrides.items():
            if not k.startswith("dr_"):
                raise ValueError(f"{s.perturbation}: {k} is not a dr_* parameter; only the episode's plant is "
                                 "perturbed here (give such a test a host env of its own)")
            cur = host.get(k, getattr(defaults, k))
            host[k] = (min(cur[0], lo), max(cur[1], hi))
    return host


# ------------------------------------------------------------------ the trials
def perturbation_trials(host, policy, scenario: int, direction: str, plants_of, num_trials: int, max_steps: int,
                        seed: int) -> dict:
    """The evaluator's trials of (scenario, direction) with the plants of `plants_of` (EnvParams)."""
    import docrl_jax.envs as envs
    start, goal = envs.eval_pair(scenario, direction)
    return rollout.run_trials(host, policy, start, goal, rollout.trial_key(seed, scenario, direction), num_trials,
                              max_steps, NOMINAL_YAW[direction], plants_of=plants_of)


_LAYOUTS: dict = {}


def held_out_layouts(params, num: int):
    """Held-out layouts 0 .. num-1 of `params`' layout ranges, stacked (a leading axis); cached."""
    key = (params, int(num))
    if key not in _LAYOUTS:
        import jax
        import jax.numpy as jnp
        from docrl_jax.envs import layouts
        _LAYOUTS[key] = jax.jit(jax.vmap(lambda i: layouts.held_out(i, params)))(jnp.arange(num))
    return _LAYOUTS[key]


def structured_layouts(params, num: int):
    """The first `num` flyable held-out structured layouts of `params` (`structures.held_out_set`),
    stacked; cached."""
    key = ("structured", params, int(num))
    if key not in _LAYOUTS:
        from docrl_jax.envs import structures
        _LAYOUTS[key] = structures.held_out_set(int(num), params).layouts
    return _LAYOUTS[key]


@dataclass
class Method:
    """A policy to benchmark: a run group (its run directories' seeds), a shipped policy or the BBA."""
    label: str
    runs: list[str] | None            # None: a shipped policy or the BBA
    sources: list[tuple[str | None, int | None]]   # (run dir, seed index within it) per seed
    seed_indices: list[int | None]    # each seed's number in the tables
    vehicle: dict = field(default_factory=dict)   # its runs' vehicle settings (evaluate.run_dirs.run_vehicle)
    shipped: str | None = None        # a shipped policy's name (docrl_jax.pretrained)


def trip_layouts(test: str, params, count: int, tank: str | None, sample=None):
    """The layouts of the trips of `test` (one per trip, stacked), or None (random trips: the
    scenario's own tank); with the tank set's names for `tanks` (`sample`: the tanks flown, indices
    into the set; None: all)."""
    from docrl_jax.evaluate import tank_sets
    if test == "held_out_layouts":
        return held_out_layouts(params, count), None
    if test == "structured":
        return structured_layouts(params, count), None
    if test == "tanks":
        names, stack = tank_sets.pick(*tank_sets.load(tank, params), sample)
        return tank_sets.repeat(stack, count), names
    return None, None


def run_benchmark(methods: Sequence[Method], cfg: dict, report=print) -> list[dict]:
    """Every test of `cfg` for every seed of every method; one row per (method, seed, test,
    perturbation, magnitude, scenario, direction, tank): `summarize`'s statistics and the row's keys
    (tank: "" but for the tanks test's rows, "all" over the set and one per tank flown).

    `cfg`: tests, scenarios, directions, settings (`sweep_settings`), env (overrides under every
    test, on top of each method's vehicle), trials, layouts, tank (the tanks test's set; tank_sample: the
    indices of its tanks flown, None for all), max_steps,
    seed, which and bba_depth_phase (how the policies load). `report(line)` gets a line per row."""
    from docrl_jax.evaluate import tank_sets
    steps, n = cfg["max_steps"], cfg["trials"]
    settings = cfg["settings"]
    rows = []

    def add(method, seed_index, test, setting, scenario, direction, trials, t0, tank=""):
        row = {"method": method.label, "seed_index": seed_index, "test": test, "perturbation": setting.perturbation,
               "magnitude": setting.magnitude, "value": setting.value,
               "parameter": PERTURBATIONS[setting.perturbation].param if setting.perturbation in PERTURBATIONS
               else "", "scenario": scenario, "direction": direction, "tank": tank, **summarize(trials),
               "seconds": round(time.time() - t0, 2)}
        rows.append(row)
        what = f"{setting.perturbation} {setting.magnitude}".strip() if test == "perturbations" else test
        what += f" {tank}" if tank else ""
        tag = "" if seed_index is None else f" seed {seed_index}"
        report(f"{method.label}{tag} | {what} | scenario {scenario} {SHORT[direction]}: {row['successes']}/"
               f"{row['trials']} success, {row['collisions']} collisions, {row['out_of_bounds']} out of bounds, "
               f"{row['timeouts']} time-outs ({row['seconds']:.1f} s)")

    trips = Setting(NONE, "", None)
    for method in methods:
        base = rollout.flown_env(method.vehicle, cfg["env"])
        host_kw = host_overrides(base, settings)
        for seed_index, (run, run_seed) in zip(method.seed_indices, method.sources):
            # The policy is built for the first env the tests fly (the BBA reads its parameters).
            own = any(t in cfg["tests"] for t in ("perturbations", "random_trips"))
            first_env = rollout.make_eval_env(cfg["scenarios"][0] if own else 0, steps, **host_kw)
            policy, _ = policies.policy_for(first_env, run, run_seed or 0, cfg["which"], cfg["bba_depth_phase"],
                                           name=method.shipped, guide=cfg.get("guide"))
            if policy.source:
                report(f"{method.label}: {Path(run).name + ': ' if run else ''}{policy.source}")
            for scenario in cfg["scenarios"] if "perturbations" in cfg["tests"] else ():
                host = rollout.make_eval_env(scenario, steps, **host_kw)
                for setting in settings:
                    plants_of = rollout.eval_params(scenario, steps, **{**base, **setting.overrides})
                    for direction in cfg["directions"]:
                        t0 = time.time()
                        trials = perturbation_trials(host, policy, scenario, direction, plants_of, n, steps,
                                                     cfg["seed"])
                        add(method, seed_index, "perturbations", setting, scenario, direction, trials, t0)
            for test in TESTS[1:]:
                if test not in cfg["tests"]:
                    continue
                scenarios = [0] if test in LAYOUT_TESTS else cfg["scenarios"]
                count = cfg["layouts"] if test in ("held_out_layouts", "structured") else n
                for scenario in scenarios:
                    host = rollout.make_eval_env(scenario, steps, **host_kw)
                    nominal = rollout.eval_params(scenario, steps, **base)
                    stack, names = trip_layouts(test, host.params, count, cfg.get("tank"), cfg.get("tank_sample"))
                    for direction in cfg["directions"]:
                        t0 = time.time()
                        start_w, goal_w = MEDIA[direction]
                        sampler = rollout.make_eval_env(scenario, steps, **host_kw, start_water_fraction=start_w,
                                                        goal_water_fraction=goal_w)
                        keys = trip_keys(cfg["seed"], test, scenario, direction, count)
                        trials = trip_trials(host, sampler, policy, keys, nominal, steps, stack)
                        if names is None:
                            add(method, seed_index, test, trips, scenario, direction, trials, t0)
                            continue
                        add(method, seed_index, test, trips, scenario, direction, trials, t0, tank_sets.ALL)
                        tank = tank_sets.tank_index(count, len(names))
                        for i in np.unique(tank):   # the tanks flown (all of them when N >= the set's size)
                            add(method, seed_index, test, trips, scenario, direction,
                                tank_sets.subset(trials, tank == i), t0, names[i])
    return rows
