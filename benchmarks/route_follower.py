"""Is every trial of the gallery's and the structured set's evaluation flyable by the vehicle itself? The
privileged route-follower (docrl_jax/baselines/route.py: it knows the tank and flies down the distance field
to the goal) flies the very trials of the robustness benchmark's `tanks` and `structured` tests (same trip
keys, same starts, goals, plants; nominal evaluation env, 500 steps) and counts arrivals per tank and
family, both ways, with what ended each failure. With --policy a learned policy flies the same trials
instead, steered by the same route (`docrl_jax/envs/guidance.py`, `route.guided`), or as it is with --unguided.

    python benchmarks/route_follower.py --out benchmarks/results/cpu/route_follower
    python benchmarks/route_follower.py --trials 35 --layouts 10     # a quick look
    python benchmarks/route_follower.py --trials 350 --layouts 1000 --policy RUN_DIR:0 --policy sac_mlp_generalist \
        --out OUT          # benchmarks/results/h100x4/route_guided (a GPU; --unguided: the same, mapless)

Writes tanks.csv and structured.csv (a row per tank or layout family and direction), failures.csv (every
trial that did not arrive: where it ended, the route left, the nearest solid) and summary.md (OUT/<label>/
per --policy).

The trials run in the evaluator's rollout (`rollout.run_from_states`); each trip's plan (`guidance.trial_plans`)
is the follower's or the guided policy's params (`Policy.trial_params`) and the diagnosis's route.
"""

from __future__ import annotations

import argparse
import csv
import math
import time
from dataclasses import replace
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.baselines import route
from docrl_jax.envs import flyability, geometry, guidance, layouts
from docrl_jax.evaluate import policies, robustness, rollout, tank_sets
from docrl_jax.evaluate.tables import SHORT, summarize

DIRECTIONS = ("air_to_water", "water_to_air")
OUTCOME_NAMES = ("arrived", "collision", "out of bounds", "time-out", "diverged")


def route_length(field, start) -> jax.Array:
    """Length (m) of the route down `field` from `start` (`flyability.route_path`); inf off the free cells."""
    path = flyability.route_path(field, start, 300)
    length = jnp.sum(jnp.linalg.norm(jnp.diff(path, axis=0), axis=-1))
    return jnp.where(jnp.isfinite(flyability.field_at(field, start)), length, jnp.inf)


_DIAGNOSES: dict = {}


def diagnose(env, plans, trips, start, end) -> dict:
    """Per trial, from its plan, its layout and where it started and ended: the route (cost at the start and
    the end, length from the start) and the gaps to the nearest obstacle and boundary (jit(vmap), per env)."""
    if id(env) not in _DIAGNOSES:
        def one(plan, layout, a, b):
            field, obstacles = plan["field"], layouts.obstacles(layout)
            gaps = jnp.concatenate([geometry.box_distances(obstacles, b), geometry.capsule_distances(obstacles, b)])
            return {"route_start": flyability.field_at(field, a), "route_m": route_length(field, a),
                    "route_end": flyability.field_at(field, b), "start_gap": geometry.signed_distance(obstacles, a),
                    "end_obstacle_gap": jnp.min(gaps), "end_obstacle": jnp.argmin(gaps),
                    "end_boundary_gap": geometry.signed_distance(layouts.boundary(layout, env.walls), b)}
        _DIAGNOSES[id(env)] = (jax.jit(jax.vmap(one)), env)
    return {k: np.asarray(v) for k, v in jax.device_get(_DIAGNOSES[id(env)][0](plans, trips, start, end)).items()}


def fly(test: str, stack, which, direction: str, seed: int, max_steps: int, crowding: float,
        pilot=None, vehicle=None, guide: bool = True) -> dict:
    """The trips of a robustness layout test (`test`: tanks or structured) in one direction, trip i in
    layout which[i] of `stack` (the benchmark's own states, plants and policy keys), flown by the evaluator's
    rollout: the route-follower, or `pilot` (a learned Policy) steered by each trip's plan with `guide`
    (`route.guided`), in its `vehicle` (`run_dirs.run_vehicle`): `rollout.trial_metrics` plus `diagnose`.
    Each trip is planned once (`guidance.trial_plans` at `crowding`): the follower's or the guided pilot's
    params, and the diagnosis's route."""
    vehicle = vehicle or {}
    host = rollout.make_eval_env(0, max_steps, **vehicle)
    start_w, goal_w = robustness.MEDIA[direction]
    sampler = rollout.make_eval_env(0, max_steps, start_water_fraction=start_w, goal_water_fraction=goal_w, **vehicle)
    keys = robustness.trip_keys(seed, test, 0, direction, len(which))
    k_reset, k_policy = jax.vmap(rollout.split_trial_key, out_axes=1)(keys)
    nominal = rollout.eval_params(0, max_steps, **vehicle)
    trips = jax.tree.map(lambda x: x[np.asarray(which)], stack)
    states = rollout.reset_states(sampler, k_reset, trips, rollout.plants_for(nominal, k_reset))
    plans = guidance.trial_plans(host, states, crowding)
    if pilot is None:
        policy = replace(route.route_follower(), trial_params=lambda params, env, s: plans)
    elif guide:
        policy = replace(route.guided(pilot), trial_params=lambda params, env, s: {**params, "plan": plans})
    else:
        policy = pilot
    trials = rollout.run_from_states(host, policy, states, k_policy, max_steps)
    trials.update(diagnose(host, plans, trips, trials["positions"][:, 0], trials["positions"][:, -1]))
    trials["goals"] = np.asarray(states.info["goal"])
    return trials


def family(tank: str) -> str:
    """A gallery tank's family: its name's first word (dead_end: two)."""
    return "dead_end" if tank.startswith("dead_end") else tank.split("_")[0]


def rows_by(groups: np.ndarray, names, trials: dict, direction: str, extra=None) -> list[dict]:
    """`summarize` per group (a row per name, then `all`), with the mean route at the start (m)."""
    out = []
    for g, name in list(enumerate(names)) + [(None, tank_sets.ALL)]:
        mask = np.ones(len(groups), bool) if g is None else groups == g
        sub = tank_sets.subset(trials, mask)
        route_m = sub["route_m"][np.isfinite(sub["route_m"])]
        arrived_s = sub["time"][sub["success"]]
        out.append({"group": name, "direction": direction, **(extra or {}), **summarize(sub),
                    "route_start_mean": float(route_m.mean()) if route_m.size else math.nan,
                    "route_start_max": float(route_m.max()) if route_m.size else math.nan,
                    "off_route_starts": int((~np.isfinite(sub["route_start"])).sum()),
                    "time_max": float(arrived_s.max()) if arrived_s.size else math.nan})
    return out


# failures.csv's measured columns: (column, the trials' array); values rounded to cm.
FAILURE_COLUMNS = (("start", "start_positions"), ("goal", "goals"), ("route_m", "route_m"),
                   ("route_cost_start", "route_start"), ("route_cost_end", "route_end"),
                   ("final_distance_m", "final_distance"), ("start_gap_m", "start_gap"),
                   ("end_obstacle_gap_m", "end_obstacle_gap"), ("end_boundary_gap_m", "end_boundary_gap"),
                   ("path_m", "path_length"))
FAILURE_FIELDS = ("test", "where", "direction", "trial", "outcome", "steps", "end", "end_obstacle_slot",
                  *(column for column, _ in FAILURE_COLUMNS))


def failures(test: str, labels, trials: dict, direction: str) -> list[dict]:
    """A row per trial that did not arrive: where it started and ended, why, the route, the nearest solid."""
    out = []
    for i in np.flatnonzero(~trials["success"]):
        r = lambda v: [round(float(x), 2) for x in np.atleast_1d(v)]  # noqa: E731
        row = {"test": test, "where": labels[i], "direction": SHORT[direction], "trial": int(i),
               "outcome": OUTCOME_NAMES[int(trials["outcome"][i])], "steps": int(trials["steps"][i]),
               "end": r(trials["positions"][i, -1]),
               "end_obstacle_slot": layouts.SLOT_NAMES[1 + int(trials["end_obstacle"][i])]}
        for column, key in FAILURE_COLUMNS:
            value = r(trials[key][i])
            row[column] = value if len(value) > 1 else value[0]
        out.append(row)
    return out


CSV_FIELDS = ("group", "direction", "trials", "successes", "collisions", "out_of_bounds", "timeouts", "diverged",
              "route_start_mean", "route_start_max", "off_route_starts", "time_mean", "time_max",
              "path_length_mean")


def write_csv(path: Path, rows, fields) -> None:
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        w.writeheader()
        w.writerows({k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()} for r in rows)


def table(rows, title: str) -> str:
    """Arrivals / trials (collisions, out of bounds, time-outs) per group, a column per direction."""
    cells = {(r["group"], r["direction"]): r for r in rows}
    groups = list(dict.fromkeys(r["group"] for r in rows))
    out = [f"### {title}\n", "| | A-W | W-A | route A-W / W-A (m, mean) | arrival A-W / W-A (s, mean; slowest) |",
           "|---|---|---|---|---|"]
    for g in groups:
        a, w = (cells[(g, d)] for d in DIRECTIONS)
        cell = lambda r: (f"{r['successes']}/{r['trials']} "  # noqa: E731
                          f"({r['collisions']}, {r['out_of_bounds']}, {r['timeouts']})")
        label = f"**{g}**" if g == tank_sets.ALL else g
        when = lambda r: f"{r['time_mean']:.0f}; {r['time_max']:.0f}"  # noqa: E731
        out.append(f"| {label} | {cell(a)} | {cell(w)} | {a['route_start_mean']:.1f} / {w['route_start_mean']:.1f} | "
                   f"{when(a)} / {when(w)} |")
    return "\n".join(out) + "\n"


def pilots(specs: list[str]) -> list[tuple[str, object, dict]]:
    """(label, Policy, vehicle) of each --policy SPEC: a shipped policy's name, or RUN_DIR[:SEED_INDEX]."""
    from docrl_jax.evaluate.run_dirs import run_vehicle
    out = []
    for spec in specs:
        from docrl_jax import pretrained
        if spec in pretrained.PRETRAINED:
            policy, _ = policies.policy_for(None, name=spec)
            out.append((spec, policy, run_vehicle(None, spec)))
            continue
        run, _, index = spec.partition(":")
        policy, name = policies.policy_for(None, run, int(index or 0), which="final")   # as the tables before
        out.append((f"{name}_s{int(index or 0)}", policy, run_vehicle(run)))
    return out


def evaluate_one(args, pilot, vehicle, names, stack, tank_of, family_names, family_of, held, out_dir) -> str:
    """The gallery's and the structured set's trials both ways, by the follower (pilot None) or `pilot`;
    the tables as text, the CSVs into `out_dir` when given."""
    from docrl_jax.envs import structures
    t_all = time.time()
    guide = not args.unguided
    tank_rows, family_rows, struct_rows, failed, seconds = [], [], [], [], {}
    for direction in DIRECTIONS:
        t0 = time.time()
        trials = fly("tanks", stack, tank_of, direction, args.seed, args.max_steps, args.crowding, pilot, vehicle, guide)
        seconds[f"tanks {SHORT[direction]}"] = round(time.time() - t0, 1)
        tank_rows += rows_by(tank_of, names, trials, direction)
        family_rows += rows_by(family_of, family_names, trials, direction)
        failed += failures("tanks", [names[t] for t in tank_of], trials, direction)
        t0 = time.time()
        trials = fly("structured", held.layouts, np.arange(args.layouts), direction, args.seed, args.max_steps,
                     args.crowding, pilot, vehicle, guide)
        seconds[f"structured {SHORT[direction]}"] = round(time.time() - t0, 1)
        fam = np.asarray(held.family)
        struct_rows += rows_by(fam, list(structures.FAMILIES), trials, direction)
        failed += failures("structured", [f"{structures.FAMILIES[f]} #{i}" for f, i in zip(fam, held.ids)],
                           trials, direction)
        print(f"{SHORT[direction]}: {seconds}", flush=True)
    seconds["total"] = round(time.time() - t_all, 1)
    text = "\n".join([table(family_rows, f"Gallery ({args.tank}) per family, {args.trials} trials each way"),
                      table(tank_rows, "Gallery per tank"),
                      table(struct_rows, f"Held-out structured set, {args.layouts} layouts, per family"),
                      "Arrivals / trials (collisions, out of bounds, time-outs).\n",
                      f"Wall time (s, compile included): {seconds}\n"])
    if out_dir:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        write_csv(out / "tanks.csv", family_rows + tank_rows, CSV_FIELDS)
        write_csv(out / "structured.csv", struct_rows, CSV_FIELDS)
        write_csv(out / "failures.csv", failed, FAILURE_FIELDS)
        (out / "summary.md").write_text(text)
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=350, help="tanks trials per direction (trial i in tank i mod 35)")
    ap.add_argument("--layouts", type=int, default=100, help="held-out structured layouts (one trial each way)")
    ap.add_argument("--tank", default="gallery", help="the tanks test's set: gallery, a tank file or a folder of them")
    ap.add_argument("--max-steps", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--crowding", type=float, default=guidance.CROWDING,
                    help="route cost near solids (guidance.plan; 0: flyability's shortest routes)")
    ap.add_argument("--look-ahead", type=int, default=guidance.LOOK_AHEAD, help="guidance.LOOK_AHEAD: cells down the route the aim may reach")
    ap.add_argument("--sight-gap", type=float, default=None,
                    help="m a line of sight keeps from every solid (default: guidance.SIGHT_GAP for the follower, "
                         "guidance.GUIDED_SIGHT_GAP for a --policy)")
    ap.add_argument("--policy", action="append", default=[], metavar="SPEC",
                    help="fly a learned policy instead of the follower, steered by the route (route.guided): a "
                         "shipped policy's name or RUN_DIR[:SEED_INDEX]; repeat for several (out/<label>/ each)")
    ap.add_argument("--unguided", action="store_true", help="with --policy: fly it as it is (mapless), same trials")
    ap.add_argument("--out", default=None, help="folder for the CSVs and summary.md")
    args = ap.parse_args()
    # The aim reads these when it is traced (below): a sweep of the guidance's own settings.
    guidance.LOOK_AHEAD = args.look_ahead
    if args.sight_gap is not None:
        guidance.SIGHT_GAP = guidance.GUIDED_SIGHT_GAP = args.sight_gap
    from docrl_jax.envs import structures
    params = rollout.make_eval_env(0, args.max_steps).params
    names, stack = tank_sets.load(args.tank, params)
    tank_of = tank_sets.tank_index(args.trials, len(names))
    family_names = list(dict.fromkeys(family(n) for n in names))
    family_of = np.array([family_names.index(family(names[t])) for t in tank_of])
    held = structures.held_out_set(args.layouts, params)
    sets = (names, stack, tank_of, family_names, family_of, held)
    if not args.policy:
        print(evaluate_one(args, None, None, *sets, args.out))
        return
    for label, pilot, vehicle in pilots(args.policy):
        out_dir = Path(args.out) / label if args.out else None
        print(f"## {label}{'' if args.unguided else ' (route-guided)'}\n")
        print(evaluate_one(args, pilot, vehicle, *sets, out_dir), flush=True)


if __name__ == "__main__":
    main()
