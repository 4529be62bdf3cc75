"""Scratch: where, relative to the sensors, are the solids the hull touches in blind collisions?
For each collision trial at its last step: the touching hull sphere's nearest solid point, in the body
frame from the vehicle's centre (the beams' origin): bearing, elevation, distance; which solid kind."""
import sys, time
import numpy as np
import jax, jax.numpy as jnp
from docrl_jax.evaluate import rollout, robustness as rb, video
from docrl_jax.evaluate.cli import run_vehicle
from docrl_jax.envs import geometry, layouts
from docrl_jax.train.program_store import enable_compile_cache
enable_compile_cache("/tmp/diag_cache")

def quat_rot(q):
    w, x, y, z = q
    return np.array([[1-2*(y*y+z*z), 2*(x*y-w*z), 2*(x*z+w*y)], [2*(x*y+w*z), 1-2*(x*x+z*z), 2*(y*z-w*x)],
                     [2*(x*z-w*y), 2*(y*z+w*x), 1-2*(x*x+y*y)]])

def contact(solids, pos, rot):
    """(nearest point on any solid to the touching sphere, the solid's kind)"""
    centres = pos[None] + geometry.HULL_SPHERE_CENTRES @ rot.T
    best = None
    for c in centres:
        c = jnp.asarray(c, jnp.float32)
        db = np.asarray(geometry.box_distances(solids, c)) if solids.box_pos.shape[0] else np.zeros(0)
        dc = np.asarray(geometry.capsule_distances(solids, c)) if solids.cap_a.shape[0] else np.zeros(0)
        for kind, d in (("box", db), ("cap", dc)):
            if d.size and (best is None or d.min() < best[0]):
                best = (float(d.min()), np.asarray(c), kind, int(d.argmin()))
    d, c, kind, i = best
    single = geometry.Solids(*(leaf[i:i+1] if (kind == "box") == (j < 3) else leaf[:0]
                               for j, leaf in enumerate(solids)))
    g = np.asarray(jax.grad(lambda p: geometry.signed_distance(single, p))(jnp.asarray(c)))
    return c - d * g, kind, i

n = int(sys.argv[1]); which = sys.argv[2]
specs = [(x.rsplit(":", 1)[0], int(x.rsplit(":", 1)[1])) for x in sys.argv[3:]]
rows = []
for (run, seed) in specs:
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
        last = out["steps"]; idx = np.arange(n)
        allr = np.concatenate([out["ranges"][idx, last], out["vertical_ranges"][idx, last]], 1)
        col = out["collision"].astype(bool)
        blind = col & (allr.min(1) >= host.params.collision_distance)
        uw = out["underwater"][idx, last].astype(bool)
        qpos = out["qpos"][idx, last]
        for t in np.nonzero(blind)[0]:
            solids = layouts.solids(jax.tree.map(lambda a: a[t], stack), host.walls) if scenario == 0 else host.solids
            nobst = (solids.box_pos.shape[0], solids.cap_a.shape[0])
            pos, rot = qpos[t, :3], quat_rot(qpos[t, 3:7])
            p, kind, i = contact(solids, pos, rot)
            v = rot.T @ (p - pos)
            bearing = np.degrees(np.arctan2(v[1], v[0])); elev = np.degrees(np.arctan2(v[2], np.hypot(v[0], v[1])))
            tilt = np.degrees(np.arccos(np.clip(rot[2, 2], -1, 1)))
            wall = kind == "box" and i < 4 and scenario == 0   # walls first in layouts.solids
            rows.append((run.split('/')[-1], seed, test, direction, int(uw[t]), kind, int(wall), bearing, elev,
                         float(np.linalg.norm(v)), float(allr[t].min()), tilt))
            print("ROW", *rows[-1], flush=True)
        print(f"{run.split('/')[-1]} s{seed} {test} {direction}: collisions {col.sum()} blind {blind.sum()} "
              f"({time.time()-t0:.0f} s)", flush=True)
