"""Quick diagnosis (not a product tool): outcomes of a run's final policy on held-out layouts and
random trips. python scratch/diag.py RUN [RUN...] --layouts 1000 --trials 200"""
import argparse, json, sys, time
import jax, jax.numpy as jnp, numpy as np
import docrl_jax.envs as envs
from docrl_jax import runs
from docrl_jax.envs import layouts

ap = argparse.ArgumentParser()
ap.add_argument("runs", nargs="+"); ap.add_argument("--layouts", type=int, default=1000)
ap.add_argument("--trials", type=int, default=200); ap.add_argument("--dr", default="")
ap.add_argument("--tests", default="held_out,held_out_dr,s3_random,s2_random,s1_random")
args = ap.parse_args()
DR = {}
for item in filter(None, args.dr.split(";")):
    k, v = item.split("="); DR[k] = tuple(float(x) if "." in x else int(x) for x in v.split(","))

def make(scenario, direction, extra):
    aw = direction == "A-W"
    return envs.make(scenario, terminate_on_arrival=True, max_episode_steps=500, sensor_noise_std=0.01, wind=True,
                     start_water_fraction=0.0 if aw else 1.0, goal_water_fraction=1.0 if aw else 0.0, **extra)

def outcomes(env, policy, n, layout_ids=None):
    keys = jax.random.split(jax.random.PRNGKey(123), n)
    def trial(key, i):
        k_reset, k_pol = jax.random.split(key)
        st = env.reset(k_reset, layout=layouts.held_out(i, env.params)) if layout_ids is not None else env.reset(k_reset)
        def body(c, k):
            st, pc, done, code = c
            pc2, a = policy.act(policy.params, pc, st.obs, st.info, k)
            ns = env.step(st, a)
            keep = lambda x, y: jnp.where(done, y, x)
            st2 = jax.tree.map(keep, ns, st); pc2 = jax.tree.map(keep, pc2, pc)
            seen = jnp.min(ns.info["ranges"]) < env.params.collision_distance
            new = jnp.where(ns.info["arrived"], 1, jnp.where(ns.info["collision"], jnp.where(seen, 2, 5), jnp.where(ns.info["out_of_bounds"], 3, jnp.where(ns.done, 4, 0))))
            code = jnp.where(done, code, new)
            return (st2, pc2, done | ns.done, code), None
        (_, _, _, code), _ = jax.lax.scan(body, (st, policy.init_carry(), jnp.zeros((), bool), jnp.zeros((), jnp.int32)), jax.random.split(k_pol, 500))
        return code
    ids = jnp.arange(n) if layout_ids is not None else jnp.zeros(n, jnp.int32)
    code = np.asarray(jax.jit(jax.vmap(trial))(keys, ids))
    return {"success": int((code == 1).sum()), "collision": int((code == 2).sum()), "blind": int((code == 5).sum()), "oob": int((code == 3).sum()),
            "timeout": int(((code == 4) | (code == 0)).sum()), "n": n}

res = {}
for run in args.runs:
    pol = runs.load_policy(run, 0, "final")
    for name, scen, extra, n, lay in [("held_out", 0, {}, args.layouts, True), ("held_out_dr", 0, DR, args.layouts, True),
                                      ("s3_random", 3, {}, args.trials, None), ("s2_random", 2, {}, args.trials, None),
                                      ("s1_random", 1, {}, args.trials, None)]:
        if (name == "held_out_dr" and not DR) or name not in args.tests.split(","):
            continue
        for d in ("A-W", "W-A"):
            t0 = time.time()
            r = outcomes(make(scen, d, extra), pol, n, lay)
            res[f"{run}|{name}|{d}"] = r
            print(run, name, d, r, f"{time.time()-t0:.1f}s", flush=True)
json.dump(res, open("diag.json", "w"), indent=1)
