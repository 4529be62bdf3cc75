"""Scratch (not a product tool): of a policy's failed held-out-layout trips and scenario-3 random trips,
how many collisions came with every beam (fan and vertical) reading above the collision distance?"""
import sys, time
import numpy as np
import jax
from docrl_jax.evaluate import rollout, robustness as rb, video
from docrl_jax.evaluate.cli import run_vehicle

from docrl_jax.train.program_store import enable_compile_cache
enable_compile_cache("/tmp/diag_cache")
n, which = int(sys.argv[1]), sys.argv[2]
specs = [(x.rsplit(":", 1)[0], int(x.rsplit(":", 1)[1])) for x in sys.argv[3:]]
steps = 500
for (run, seed), test, scenario in [(s, t, c) for s in specs for t, c in (("held_out_layouts", 0), ("random_trips", 3))]:
  base = rollout.flown_env(run_vehicle(run), {})
  if True:
    host = rollout.make_eval_env(scenario, steps, **base)
    policy, _ = video.policy_for(host, run, seed, which)
    nominal = rollout.eval_params(scenario, steps, **base)
    stack = rb.held_out_layouts(host.params, n) if scenario == 0 else None
    for direction in ("air_to_water", "water_to_air"):
        t0 = time.time()
        sw, gw = rb.MEDIA[direction]
        sampler = rollout.make_eval_env(scenario, steps, **base, start_water_fraction=sw, goal_water_fraction=gw)
        keys = rb.trip_keys(0, test, scenario, direction, n)
        k_reset, k_pol = jax.vmap(rollout.split_trial_key, out_axes=1)(keys)
        states = rollout.reset_states(sampler, k_reset, stack, rollout.plants_for(nominal, k_reset))
        out = rollout.run_from_states(host, policy, states, k_pol, steps, render=True)
        last = out["steps"]                       # records index T is after step T
        idx = np.arange(n)
        fan = out["ranges"][idx, last]            # (n, 20)
        vert = out["vertical_ranges"][idx, last]
        allr = np.concatenate([fan, vert], 1)
        seen = allr.min(1) < host.params.collision_distance
        m = allr.min(1)[col_ := out["collision"].astype(bool)]
        bins = np.histogram(m, [0, 0.5, 1.0, 2.0, 100])[0].tolist()
        col = out["collision"]
        uw = out["underwater"][idx, last]
        print(f"{run.split('/')[-1]} s{seed} {test} S{scenario} {direction}: success {out['success'].sum()}/{n}, "
              f"collisions {col.sum()} (seen {int((col & seen).sum())}, blind {int((col & ~seen).sum())}; "
              f"blind under water {int((col & ~seen & uw.astype(bool)).sum())}), oob {out['out_of_bounds'].sum()}, "
              f"timeout {out['timeout'].sum()}; collisions by nearest range <0.5/0.5-1/1-2/>2 m: {bins} ({time.time()-t0:.0f} s)", flush=True)
