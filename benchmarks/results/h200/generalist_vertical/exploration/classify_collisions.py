"""Classify collisions of a run's final policy (seed index 0) by the contact normal at the touching hull sphere:
seen<0.5 (a fan range below the collision distance), above / below (hull contact with an obstacle above /
below), side(seen) / side(blind). A diagnosis, not a packaged tool:
    python classify_collisions.py RUN SCENARIO DIRECTION N      # scenario 0: the first N held-out layouts"""
import sys, numpy as np, jax, jax.numpy as jnp
from docrl_jax.evaluate import robustness as R, rollout, video
from docrl_jax.evaluate.cli import run_vehicle
from docrl_jax.envs import geometry, physics, layouts as L
run, scen, direction, n = sys.argv[1], int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
veh = run_vehicle(run)
host = rollout.make_eval_env(scen, 500, **veh)
policy, _ = video.policy_for(host, run, 0, "final", None)
sw, gw = R.MEDIA[direction]
sampler = rollout.make_eval_env(scen, 500, **veh, start_water_fraction=sw, goal_water_fraction=gw)
test = "random_trips" if scen else "held_out_layouts"
keys = R.trip_keys(0, test, scen, direction, n)
k_reset, k_policy = jax.vmap(rollout.split_trial_key, out_axes=1)(keys)
nominal = rollout.eval_params(scen, 500, **veh)
stack = R.held_out_layouts(host.params, n) if scen == 0 else None
states = rollout.reset_states(sampler, k_reset, stack, rollout.plants_for(nominal, k_reset))
out = rollout.run_from_states(host, policy, states, k_policy, 500, render=True)
def classify(solids, q, minr, cd):
    p = jnp.asarray(q[:3]); rot = physics.quat_to_mat(jnp.asarray(q[3:7]))
    centres = p[None] + jnp.asarray(geometry.HULL_SPHERE_CENTRES) @ rot.T
    d = jax.vmap(lambda c: geometry.signed_distance(solids, c))(centres)
    c = centres[jnp.argmin(d)]
    g = jax.grad(lambda x: geometry.signed_distance(solids, x))(c)
    nz = -float(g[2]) / (float(jnp.linalg.norm(g)) + 1e-9)
    if float(jnp.min(d)) - geometry.HULL_SPHERE_RADIUS >= 0 and minr < cd:
        return "seen<0.5"
    return "above" if nz > 0.7 else ("below" if nz < -0.7 else ("side(seen)" if minr < 1.0 else "side(blind)"))
from collections import Counter
cnt = Counter()
for i in np.where(out["collision"])[0]:
    T = int(out["steps"][i]); q = out["qpos"][i, T]
    if scen == 0:
        lay = jax.tree.map(lambda x: x[i], states.sim.layout); solids = L.solids(lay, host.walls)
    else:
        solids = host.solids
    k = classify(solids, q, float(out["ranges"][i, T].min()), host.params.collision_distance)
    uw = "water" if q[2] < 0 else "air"
    cnt[(k, uw)] += 1
print(run.split('/')[-1], scen, direction, "n", n, "success", int(out["success"].sum()), "collisions", int(out["collision"].sum()), dict(sorted(cnt.items())))
