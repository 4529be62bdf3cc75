"""What flying on the vehicle's own map costs: evaluation env steps per second of one policy flown mapless,
down the tank's route (--guide tank) and down the route planned on its own beams (--guide sensors), on the
same trials of a tank set (docrl_jax.evaluate.tank_trials), compiled first, then timed.

    python benchmarks/own_map_cost.py [--policy sac_mlp_tanks] [--trials 1000] [--tank gallery] [--repeats 3]
        [--modes mapless,tank,sensors] [--belief SWEEPS=1 ...] [--out cost.json]

`--belief NAME=VALUE` sets one of docrl_jax.envs.belief's settings (REPLAN, SWEEPS, GAP_REACH, UNKNOWN_GAP, ...)
for the run: what a setting costs (REPLAN=1 plans every step).

A trial runs its whole `--max-steps` scan (the rollout records every step), so env steps = trials x steps.
Prints one line per mode (median over repeats) and the ratio to mapless; --out writes them as JSON.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--policy", default="sac_mlp_tanks")
    p.add_argument("--trials", type=int, default=1000)
    p.add_argument("--tank", default="gallery")
    p.add_argument("--max-steps", type=int, default=500)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--modes", default="mapless,tank,sensors")
    p.add_argument("--belief", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    modes = args.modes.split(",")
    if not set(modes) <= {"mapless", "tank", "sensors"}:
        p.error(f"--modes {args.modes!r}: valid modes are mapless, tank, sensors")

    import jax

    from docrl_jax import pretrained
    from docrl_jax.envs import belief
    from docrl_jax.evaluate import policies, rollout, tank_sets, tank_trials
    settings = dict(kv.split("=", 1) for kv in args.belief)
    for name, value in settings.items():
        setattr(belief, name, type(getattr(belief, name))(value))
    env_kw = rollout.flown_env(pretrained.vehicle(args.policy), {})
    host = rollout.make_eval_env(0, args.max_steps, **env_kw)
    _, stack = tank_sets.load(args.tank, host.params)
    rows = []
    for mode in modes:
        guide = None if mode == "mapless" else mode
        policy, label = policies.policy_for(host, name=args.policy, guide=guide)
        t0 = time.perf_counter()
        tank_trials.run(policy, stack, "water_to_air", args.trials, args.max_steps, 0, env_kw)
        first = time.perf_counter() - t0
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            trials = tank_trials.run(policy, stack, "water_to_air", args.trials, args.max_steps, 0, env_kw)
            times.append(time.perf_counter() - t0)
        seconds = statistics.median(times)
        rows.append({"mode": mode, "label": label, "belief": settings, "trials": args.trials, "max_steps": args.max_steps,
                     "first_call_s": round(first, 2), "seconds": [round(t, 3) for t in times],
                     "env_steps_per_s": round(args.trials * args.max_steps / seconds),
                     "success": float(trials["success"].mean())})
    base = rows[0]["env_steps_per_s"] if modes[0] == "mapless" else None
    for r in rows:
        r["vs_mapless"] = base and round(r["env_steps_per_s"] / base, 3)
        ratio = f"{r['vs_mapless']:.2f}x mapless" if base else "mapless not run"
        print(f"{r['mode']:8s} {settings or ''} {r['env_steps_per_s']:>10,d} env steps/s ({ratio}; "
              f"median of {args.repeats}; first call {r['first_call_s']} s; W-A success {100 * r['success']:.0f} %)")
    if args.out:
        device = jax.devices()[0].device_kind
        with open(args.out, "w") as f:
            json.dump({"device": device, "jax": jax.__version__, "policy": args.policy, "tank": args.tank,
                       "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
