"""Peers on our environment: Brax's own SAC and PPO trainers through the Brax adapter, judged by OUR
evaluation, and the steps/s of a CPU Gymnasium vector loop. For the GPU machine; not part of CI.

    python benchmarks/peers.py --trainers sac ppo --seeds 0 1 2 --budget-s 600
    python benchmarks/peers.py --trainers sac --sweep num_envs=128,512 --sweep grad_updates_per_step=16,64
    python benchmarks/peers.py --trainers ppo --sweep unroll_length=5,10 --set ppo.num_envs=8192
    python benchmarks/peers.py --trainers ppo --recipe playground_locomotion   # MuJoCo Playground's recipe
    python benchmarks/peers.py --gym-loop --gym-num-envs 1 16 64     # NumPy-driven Gymnasium loop, steps/s
    python benchmarks/peers.py --smoke                                # everything tiny, CPU, 1-2 min

Time to success. Every (trainer, configuration, seed) is its own launch of this script (`--worker`),
so its clock starts before Python starts and includes imports, environment construction and every
compilation, as in benchmarks/time_to_success.py. The trainer is `brax.training.agents.{sac,ppo}.train`,
unchanged, on `BraxHUAUV(scenario=2)` (docrl_jax/envs/brax_env.py; Brax's own Vmap/Episode/AutoReset
wrappers, episode_length 500) with the env settings of our config --env-from (default td3_lstm: the
same training start distribution, `goal_clearance` 0.6, as the trainer it is compared with). At each of Brax's evaluation points the worker takes the policy's
current parameters (PPO: `policy_params_fn`; SAC, which has no such callback in brax 0.14.2: the
checkpoint Brax writes to `checkpoint_logdir` just before calling `progress_fn`) and runs OUR
evaluation (docrl_jax/evaluate/rollout.py `evaluate_policy`): the paper's air_to_water and water_to_air pairs
of scenario 2, 100 trials each, deterministic policy (Brax's `deterministic=True`: the Gaussian's
mode), wind and 0.01 m range noise, at most 500 steps, the paper's reward. The clock stops at the first
evaluation with both directions >= --target (90 %): `time_to_target_s` counts everything up to the
end of that evaluation; `time_to_target_excl_eval_s` leaves out the time spent in our evaluations
(which are not part of the peer's trainer; Brax's own evaluator, its checkpoints and compilation stay
in). The run then stops (Brax has no early stop: the callback raises) unless --to-end. A run that
does not reach the target within --budget-s is stopped at its next evaluation and reported as not
reached, with its best.

Hyperparameters: --recipe picks a published recipe (docrl_jax.benchmarking.PEER_RECIPES: Brax's Ant recipes, the default,
or MuJoCo Playground's dm_control-suite or locomotion recipes, networks included), with our episode
length 500. --set and --sweep change its train() arguments (KEY or TRAINER.KEY; a KEY applies to each
trainer whose `train` takes it; unknown keys are an error naming the valid ones).

Writes peers_<tag>.json (meta, every run with its evaluation curve) and peers_<tag>.md (one row per
run, and the median over seeds per trainer and configuration) into --out; --gym-loop writes
peers_gym_loop_<tag>.json / .md.
"""

from __future__ import annotations

import argparse
import inspect
import itertools
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time

from docrl_jax.benchmarking import DEFAULT_PEER_RECIPE, PEER_RECIPES, peer_recipe, run_meta, write_results

TRAINERS = ("sac", "ppo")
SMOKE = {
    "sac": dict(num_timesteps=64, num_evals=2, episode_length=20, num_envs=4, batch_size=8, grad_updates_per_step=1,
                min_replay_size=8, max_replay_size=512, num_eval_envs=2),
    "ppo": dict(num_timesteps=64, num_evals=2, episode_length=20, num_envs=4, batch_size=2, unroll_length=4,
                num_minibatches=2, num_updates_per_batch=1, num_eval_envs=2),
}
SMOKE_NETWORKS = {"sac": {"hidden_layer_sizes": (8, 8)},
                  "ppo": {"policy_hidden_layer_sizes": (8,), "value_hidden_layer_sizes": (8,)}}
# Brax's own evaluation numbers recorded beside ours (its return uses our reward, see brax_env.py).
BRAX_METRICS = ("eval/episode_reward", "eval/avg_episode_length", "eval/episode_arrived", "eval/episode_collision",
                "eval/episode_out_of_bounds")
# XLA's cheap CPU optimisation: on the smoke run compiling dominates, so it halves its time.
SMOKE_XLA_FLAGS = "--xla_backend_optimization_level=0 --xla_llvm_disable_expensive_passes=true"


# ----------------------------------------------------------------------------------------- options

def _value(text: str):
    """A --set/--sweep value: int, float, bool, or a string."""
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return {"true": True, "false": False}.get(text.lower(), text)


def _train_params(trainer: str) -> set[str]:
    if trainer == "sac":
        from brax.training.agents.sac import train as mod
    else:
        from brax.training.agents.ppo import train as mod
    return set(inspect.signature(mod.train).parameters) - _NOT_SETTABLE


# Set by this script itself (seed: --seeds; the networks: the recipe), or not meaningful here.
_NOT_SETTABLE = {"environment", "progress_fn", "policy_params_fn", "seed", "network_factory", "checkpoint_logdir",
                 "eval_env", "randomization_fn", "wrap_env", "wrap_env_fn", "restore_checkpoint_path",
                 "save_checkpoint_path", "restore_params", "restore_value_fn"}


def _targets(key: str, trainers, option: str) -> list[tuple[str, str]]:
    """(trainer, param) pairs a KEY or TRAINER.KEY of --set/--sweep applies to; errors name valid keys."""
    trainer, _, name = key.rpartition(".")
    chosen = [trainer] if trainer else list(trainers)
    if trainer and trainer not in TRAINERS:
        raise SystemExit(f"{option} {key!r}: unknown trainer {trainer!r}; valid: {', '.join(TRAINERS)}")
    out = [(t, name) for t in chosen if name in _train_params(t)]
    if not out:
        valid = sorted(set().union(*(_train_params(t) for t in chosen)))
        raise SystemExit(f"{option} {key!r}: no trainer among {chosen} takes {name!r}; valid keys: {', '.join(valid)}")
    return out


def configs(args) -> list[tuple[str, dict, dict, str]]:
    """(trainer, brax train kwargs, network kwargs, label naming the recipe and sweep point) for every
    trainer and sweep point."""
    recipes = {t: peer_recipe(args.recipe, t) for t in args.trainers}
    base = {t: {**recipes[t][0], **(SMOKE[t] if args.smoke else {})} for t in args.trainers}
    nets = {t: {**recipes[t][1], **(SMOKE_NETWORKS[t] if args.smoke else {})} for t in args.trainers}
    for item in args.set:
        key, sep, val = item.partition("=")
        if not sep:
            raise SystemExit(f"--set {item!r}: expected KEY=VALUE or TRAINER.KEY=VALUE")
        for t, name in _targets(key, args.trainers, "--set"):
            base[t][name] = _value(val)
    sweeps: dict[str, list[tuple[str, list]]] = {t: [] for t in args.trainers}
    for item in args.sweep:
        key, sep, vals = item.partition("=")
        if not sep or not vals:
            raise SystemExit(f"--sweep {item!r}: expected KEY=V1,V2,... or TRAINER.KEY=V1,V2,...")
        for t, name in _targets(key, args.trainers, "--sweep"):
            sweeps[t].append((name, [_value(v) for v in vals.split(",")]))
    out = []
    for t in args.trainers:
        names = [n for n, _ in sweeps[t]]
        for combo in itertools.product(*[v for _, v in sweeps[t]]) if names else [()]:
            point = dict(zip(names, combo))
            name = [t] + ([args.recipe] if args.recipe != DEFAULT_PEER_RECIPE else [])
            out.append((t, {**base[t], **point}, nets[t], " ".join(name + [f"{k}={v}" for k, v in point.items()])))
    return out


def env_settings(config_name: str) -> dict:
    """The env keyword overrides of our packaged config `config_name` (what our trainer trains on)."""
    from docrl_jax.config import env_kwargs, load_config
    c = load_config(config_name, backend="cpu")
    if c.env.scenario != 2:
        raise SystemExit(f"--env-from {config_name}: trains on scenario {c.env.scenario}; the peers train on 2")
    return env_kwargs(c)


# ----------------------------------------------------------------------------------------- worker

class _Stop(Exception):
    """Raised from Brax's callback to end a run: target reached or budget spent."""


def worker(spec: dict) -> None:
    """One launch: trains `spec['trainer']` with `spec['config']`, evaluating at each Brax evaluation."""
    launch = spec["launch"]
    import functools

    import jax.numpy as jnp

    from docrl_jax import evaluate
    from docrl_jax.envs.brax_env import BraxHUAUV   # applies the jax.device_put_replicated shim
    from docrl_jax.policy import Policy

    trainer, cfg = spec["trainer"], dict(spec["config"])
    env = BraxHUAUV(scenario=spec["scenario"], episode_length=cfg["episode_length"], **spec["env"])
    nets = {k: tuple(v) if isinstance(v, list) else v for k, v in spec["networks"].items()}
    result = {"trainer": trainer, "recipe": spec["recipe"], "seed": spec["seed"], "config": cfg,
              "networks": spec["networks"], "env": spec["env"],
              "evals": [], "reached": False, "stop_reason": "end"}
    eval_total = 0.0
    state: dict = {}

    def save():
        with open(spec["result_path"], "w") as f:
            json.dump(result, f, indent=1)

    def judge(step: int, make_policy, params) -> None:
        nonlocal eval_total
        t0 = time.time()
        if "act" not in state:   # one act and init_carry per run: our rollout is cached by their ids,
            def act(p, carry, obs, info, key):   # so it compiles once, not at every evaluation
                action, _ = make_policy(p, deterministic=True)(obs, key)
                return carry, action
            state["act"], state["init_carry"] = act, (lambda: jnp.zeros(()))
        policy = Policy(f"brax_{trainer}", params, state["init_carry"], state["act"])
        rows = evaluate.evaluate_policy(policy, f"brax_{trainer}", [spec["scenario"]], evaluate.DIRECTIONS,
                                        spec["trials"], spec["max_steps"], seed=spec["eval_seed"])
        succ = {r["direction"]: r["success_rate"] for r, _ in rows}
        spent = time.time() - t0
        eval_total += spent
        now = time.time() - launch
        result["evals"].append({"env_steps": int(step), "wall_s": round(now, 2), "eval_s": round(spent, 2),
                                "air_to_water": succ["air_to_water"], "water_to_air": succ["water_to_air"],
                                **{k: float(v) for k, v in state.pop("metrics", {}).items() if k in BRAX_METRICS}})
        print(f"[{trainer} seed {spec['seed']}] step {step:,} at {now:.1f} s: A-W {succ['air_to_water']:.2f}, "
              f"W-A {succ['water_to_air']:.2f} (our evaluation {spent:.1f} s)", flush=True)
        if not result["reached"] and min(succ.values()) >= spec["target"]:
            result.update(reached=True, time_to_target_s=round(now, 2),
                          time_to_target_excl_eval_s=round(now - eval_total, 2), env_steps_at_target=int(step))
            if not spec["to_end"]:
                result["stop_reason"] = "target"
                save()
                raise _Stop
        save()
        if now > spec["budget_s"]:
            result["stop_reason"] = "budget"
            raise _Stop

    kwargs = dict(cfg, seed=spec["seed"])
    t_start = time.time()
    try:
        if trainer == "ppo":
            from brax.training.agents.ppo import networks as ppo_networks
            from brax.training.agents.ppo import train as ppo
            def progress(step, metrics):   # called after policy_params_fn: Brax's numbers join our row
                if result["evals"] and result["evals"][-1]["env_steps"] == int(step):
                    result["evals"][-1].update({k: float(metrics[k]) for k in BRAX_METRICS if k in metrics})

            def params_fn(step, make_policy, params):
                if step > 0:   # as for SAC, no evaluation of the untrained policy
                    judge(step, make_policy, params)

            ppo.train(environment=env, network_factory=functools.partial(ppo_networks.make_ppo_networks, **nets),
                      progress_fn=progress, policy_params_fn=params_fn, **kwargs)
        else:
            from brax.training import checkpoint as brax_checkpoint
            from brax.training.acme import running_statistics
            from brax.training.agents.sac import networks as sac_networks
            from brax.training.agents.sac import train as sac
            network = sac_networks.make_sac_networks(
                env.observation_size, env.action_size, **nets,
                preprocess_observations_fn=(running_statistics.normalize if cfg.get("normalize_observations")
                                            else (lambda x, y: x)))
            make_policy = sac_networks.make_inference_fn(network)
            ckpt_dir = tempfile.mkdtemp(prefix="peers_sac_ckpt_")

            def progress(step, metrics):
                if step == 0:
                    return   # Brax's evaluation before training: no checkpoint yet
                state["metrics"] = metrics
                params = brax_checkpoint.load(os.path.join(ckpt_dir, f"{int(step):012d}"))
                judge(step, make_policy, params)

            sac.train(environment=env, network_factory=functools.partial(sac_networks.make_sac_networks, **nets),
                      progress_fn=progress, checkpoint_logdir=ckpt_dir, **kwargs)
    except _Stop:
        pass
    result["elapsed_s"] = round(time.time() - launch, 2)
    result["startup_s"] = round(t_start - launch, 2)
    result["eval_total_s"] = round(eval_total, 2)
    save()


# ----------------------------------------------------------------------------------------- parent

def run_one(args, trainer: str, cfg: dict, nets: dict, seed: int, out_dir: str, tag: str, index: int) -> dict:
    log_path = os.path.join(out_dir, f"peers_{tag}_{trainer}{index}_seed{seed}.log")
    result_path = log_path[:-4] + ".json"
    spec = {"trainer": trainer, "recipe": args.recipe, "config": cfg, "seed": seed,
            "networks": {k: list(v) if isinstance(v, tuple) else v for k, v in nets.items()},
            "scenario": 2, "trials": args.trials, "max_steps": args.max_steps, "eval_seed": args.eval_seed,
            "target": args.target, "budget_s": args.budget_s, "to_end": args.to_end, "result_path": result_path,
            "env": env_settings(args.env_from)}
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    if args.smoke:
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} {SMOKE_XLA_FLAGS}"
    spec["launch"] = time.time()
    with open(log_path, "w") as log:
        proc = subprocess.Popen([sys.executable, os.path.abspath(__file__), "--worker", json.dumps(spec)],
                                stdout=log, stderr=subprocess.STDOUT, env=env)
        try:
            # The worker stops itself at its first evaluation past the budget; this is the backstop.
            proc.wait(timeout=args.budget_s + args.grace_s)
        except subprocess.TimeoutExpired:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
    try:
        with open(result_path) as f:
            res = json.load(f)
    except (OSError, json.JSONDecodeError):
        res = {"trainer": trainer, "recipe": args.recipe, "seed": seed, "config": cfg, "evals": [], "reached": False}
    if proc.returncode != 0:
        res["stop_reason"] = f"worker exited {proc.returncode} (see {os.path.basename(log_path)})"
    res["log"] = os.path.basename(log_path)
    best = {d: max([e[d] for e in res["evals"]] or [float("nan")]) for d in ("air_to_water", "water_to_air")}
    res["best"] = best
    res["final"] = res["evals"][-1] if res["evals"] else None
    return res


def peers(args) -> int:
    tag = args.tag or ("smoke" if args.smoke else "_".join(args.trainers))
    meta = run_meta()
    os.makedirs(args.out, exist_ok=True)
    runs, summary = [], []
    cfgs = configs(args)
    for index, (trainer, cfg, nets, label) in enumerate(cfgs):
        for seed in args.seeds:
            r = run_one(args, trainer, cfg, nets, seed, args.out, tag, index)
            r["label"] = label
            runs.append(r)
            print(f"{r['label']} seed {seed}: " + (
                f"{args.target:.0%} both ways at {r['time_to_target_s']} s ({r['time_to_target_excl_eval_s']} s "
                f"without our evaluations; {r['env_steps_at_target']:,} env steps)" if r["reached"] else
                f"not reached ({r.get('stop_reason')}; best A-W {r['best']['air_to_water']}, "
                f"W-A {r['best']['water_to_air']})") + f"; {len(r['evals'])} evaluations", flush=True)
            write_tables(args, meta, runs, tag)
    for label in dict.fromkeys(r["label"] for r in runs):
        times = [r.get("time_to_target_s") for r in runs if r["label"] == label]
        med = statistics.median([t if t is not None else float("inf") for t in times])
        summary.append(f"{label}: median time to target " + (f"{med} s" if med != float("inf") else "not reached")
                       + f", reached {sum(t is not None for t in times)}/{len(times)}")
    write_tables(args, meta, runs, tag, summary)
    print("\n".join(summary))
    return 0


def write_tables(args, meta: dict, runs: list[dict], tag: str, summary: list[str] = ()) -> None:
    """peers_<tag>.md (one row per run, then the medians) and peers_<tag>.json (every run in full).
    Called after every run, so a sweep that fails part-way keeps what it measured."""
    rows = [{"label": x["label"], "seed": x["seed"], "reached": x["reached"],
             "t": x.get("time_to_target_s", "–"), "t_excl": x.get("time_to_target_excl_eval_s", "–"),
             "steps": x.get("env_steps_at_target", "–"), "evals": len(x["evals"]),
             "best": f"{x['best']['air_to_water']} / {x['best']['water_to_air']}",
             "final": f"{x['final']['air_to_water']} / {x['final']['water_to_air']}" if x["final"] else "–",
             "stop": x.get("stop_reason", "?"), "elapsed": x.get("elapsed_s", "–")} for x in runs]
    settings = {"recipe": args.recipe, "env_from": args.env_from, "env": env_settings(args.env_from), "target": args.target, "budget_s": args.budget_s, "trials": args.trials, "max_steps": args.max_steps,
                "eval_seed": args.eval_seed, "to_end": args.to_end, "smoke": args.smoke}
    write_results(args.out, f"peers_{tag}", f"Brax peers on our env: launch to {args.target:.0%} in both directions",
                  meta, rows, [("trainer / config", "label"), ("seed", "seed"), ("reached", "reached"),
                               ("time to target (s)", "t"), ("without our evaluations (s)", "t_excl"),
                               ("env steps", "steps"), ("evaluations", "evals"), ("best A-W / W-A", "best"),
                               ("final A-W / W-A", "final"), ("stop", "stop"), ("elapsed (s)", "elapsed")])
    if summary:
        with open(os.path.join(args.out, f"peers_{tag}.md"), "a") as f:
            f.write("\n" + "\n".join(f"- {s}" for s in summary) + "\n")
    with open(os.path.join(args.out, f"peers_{tag}.json"), "w") as f:
        json.dump({**meta, **settings, "summary": list(summary), "runs": runs}, f, indent=1)


# ----------------------------------------------------------------------------------------- gym loop

def gym_loop(args) -> int:
    """Env steps/s of one Gymnasium vector loop on this process's default JAX device, driven from
    NumPy with random actions (the action space's own sampler), as a NumPy-based learner would."""
    import numpy as np

    from docrl_jax.envs.gym_env import HUAUVVectorEnv
    tag = args.tag or ("smoke" if args.smoke else "default")
    # The 1-minute load average before starting: a CPU loop's rate depends on what else runs.
    meta = {**run_meta(), "loadavg_1min_at_start": round(os.getloadavg()[0], 2), "cpu_count": os.cpu_count()}
    rows = []
    for n in args.gym_num_envs:
        t0 = time.time()
        venv = HUAUVVectorEnv(n, scenario=2)
        venv.reset(seed=0)
        venv.action_space.seed(0)
        for _ in range(args.gym_warmup):            # compiles; includes an auto-reset or two
            venv.step(venv.action_space.sample())
        startup = time.time() - t0
        ends, t0 = 0, time.time()
        for _ in range(args.gym_steps):
            _, _, terminated, truncated, _ = venv.step(venv.action_space.sample())
            ends += int(np.sum(terminated | truncated))
        dt = time.time() - t0
        rows.append({"num_envs": n, "vector_steps": args.gym_steps, "seconds": round(dt, 3),
                     "env_steps_per_s": round(n * args.gym_steps / dt, 1),
                     "vector_steps_per_s": round(args.gym_steps / dt, 1), "episodes_ended": ends,
                     "startup_s": round(startup, 1)})
        print(f"gym loop, {n} envs: {rows[-1]['env_steps_per_s']:,} env steps/s "
              f"({rows[-1]['vector_steps_per_s']} vector steps/s; start-up and compile {startup:.1f} s)", flush=True)
        write_results(args.out, f"peers_gym_loop_{tag}", "Gymnasium vector loop (NumPy in and out, random actions; "
                      f"{meta['cpu_count']} CPUs, load {meta['loadavg_1min_at_start']} at start)",
                      meta, rows, [("envs", "num_envs"), ("env steps/s", "env_steps_per_s"),
                                   ("vector steps/s", "vector_steps_per_s"), ("steps timed", "vector_steps"),
                                   ("episodes ended", "episodes_ended"), ("start-up + compile (s)", "startup_s")])
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--trainers", nargs="+", choices=TRAINERS, default=list(TRAINERS))
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--recipe", default=DEFAULT_PEER_RECIPE, choices=sorted(PEER_RECIPES),
                    help="the published recipe the runs start from (PEER_RECIPES; default: Brax's Ant recipes)")
    ap.add_argument("--set", action="append", default=[], metavar="[TRAINER.]KEY=VALUE",
                    help="a brax train() argument for every run (e.g. sac.learning_rate=3e-4, num_envs=256)")
    ap.add_argument("--sweep", action="append", default=[], metavar="[TRAINER.]KEY=V1,V2",
                    help="a grid axis (e.g. num_envs=128,512; sac.grad_updates_per_step=16,64; ppo.unroll_length=5,10)")
    ap.add_argument("--target", type=float, default=0.9)
    ap.add_argument("--env-from", default="td3_lstm",
                    help="our config whose env settings (e.g. goal_clearance) the peers train with")
    ap.add_argument("--budget-s", type=float, default=900.0, help="per run, from its launch")
    ap.add_argument("--grace-s", type=float, default=600.0, help="beyond the budget before a run is killed")
    ap.add_argument("--to-end", action="store_true", help="train to num_timesteps even after the target")
    ap.add_argument("--trials", type=int, default=100, help="our evaluation: trials per direction (paper: 100)")
    ap.add_argument("--max-steps", type=int, default=500, help="our evaluation: step limit of a trial (paper: 500)")
    ap.add_argument("--eval-seed", type=int, default=0)
    ap.add_argument("--gym-loop", action="store_true", help="measure the Gymnasium vector loop instead")
    ap.add_argument("--gym-num-envs", type=int, nargs="+", default=[1, 16, 64])
    ap.add_argument("--gym-steps", type=int, default=200, help="timed vector steps per size")
    ap.add_argument("--gym-warmup", type=int, default=5)
    ap.add_argument("--smoke", action="store_true",
                    help="everything tiny on CPU (~1-2 min): both trainers, one seed, 4 trials of 20 steps, target 0 "
                         "(so the first evaluation stops the run), a 4-env gym loop; writes to $TMPDIR/peers_smoke")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "results"))
    ap.add_argument("--tag", default=None, help="name of the result files")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        worker(json.loads(args.worker))
        return 0
    if args.smoke:
        # Target 0: the first evaluation "reaches" it, so the stop-at-target path runs too.
        args.seeds, args.trials, args.max_steps, args.budget_s, args.grace_s = [0], 4, 20, 240.0, 120.0
        args.target = 0.0
        args.gym_num_envs, args.gym_steps = [4], 20
        if args.out == ap.get_default("out"):
            args.out = os.path.join(tempfile.gettempdir(), "peers_smoke")
        peers(args)
        return gym_loop(args)
    return gym_loop(args) if args.gym_loop else peers(args)


if __name__ == "__main__":
    sys.exit(main())
