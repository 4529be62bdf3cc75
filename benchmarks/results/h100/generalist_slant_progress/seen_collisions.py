"""Scratch diagnosis: what ends the collision trials of a run's seed, and did its beams see it coming?
For each collision trial at its last step: the fan's smallest range (below 0.5 m: the fan ended it,
else a hull contact), the smallest range of every beam (fan, vertical, slanted) then and 3 control
steps (0.6 s) before, and the speed over the last step.
    python seen_collisions.py N final RUN:SEED ...   (prints one summary line per test and direction)"""
import sys, time
import numpy as np
import jax
from docrl_jax.evaluate import rollout, robustness as rb, video
from docrl_jax.evaluate.cli import run_vehicle
from docrl_jax.train.program_store import enable_compile_cache
enable_compile_cache("/tmp/diag_cache")

n = int(sys.argv[1]); which = sys.argv[2]
for spec in sys.argv[3:]:
    run, seed = spec.rsplit(":", 1)[0], int(spec.rsplit(":", 1)[1])
    for test, scenario in (("held_out_layouts", 0), ("random_trips", 3)):
        base = rollout.flown_env(run_vehicle(run), {})
        host = rollout.make_eval_env(scenario, 500, **base)
        policy, _ = video.policy_for(host, run, seed, which)
        nominal = rollout.eval_params(scenario, 500, **base)
        stack = rb.held_out_layouts(host.params, n) if scenario == 0 else None
        for direction in ("air_to_water", "water_to_air"):
            t0 = time.time()
            sw, gw = rb.MEDIA[direction]
            sampler = rollout.make_eval_env(scenario, 500, **base, start_water_fraction=sw, goal_water_fraction=gw)
            keys = rb.trip_keys(0, test, scenario, direction, n)
            k_reset, k_pol = jax.vmap(rollout.split_trial_key, out_axes=1)(keys)
            states = rollout.reset_states(sampler, k_reset, stack, rollout.plants_for(nominal, k_reset))
            out = rollout.run_from_states(host, policy, states, k_pol, 500, render=True)
            last = out["steps"]; col = np.nonzero(out["collision"].astype(bool))[0]
            fan = out["ranges"][col, last[col]].min(1)
            every = lambda k: np.concatenate([out["ranges"][col, k], out["vertical_ranges"][col, k]], 1).min(1)
            now, before = every(last[col]), every(np.maximum(last[col] - 3, 0))
            pos = out["positions"]
            speed = np.linalg.norm(pos[col, last[col]] - pos[col, np.maximum(last[col] - 1, 0)], axis=1) / 0.2
            d = host.params.collision_distance
            print(f"{run.split('/')[-1]} s{seed} {test} {direction}: collisions {col.size}; ended by the fan "
                  f"{int((fan < d).sum())}, hull contact seen by a vertical or slanted beam {int(((fan >= d) & (now < d)).sum())}, "
                  f"blind {int((now >= d).sum())}; some beam under 1 m 0.6 s before: {int((before < 1.0).sum())}; "
                  f"speed m/s median {np.median(speed) if col.size else float('nan'):.2f} "
                  f"(fan-ended {np.median(speed[fan < d]) if (fan < d).any() else float('nan'):.2f}) ({time.time() - t0:.0f} s)",
                  flush=True)
