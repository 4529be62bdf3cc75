#!/usr/bin/env bash
# On this repository's 2-core CPU: the perturbations of scenarios 1-2 (50 trials) for this round's
# launches, the same command as ../generalist_hull_margin/cpu_eval.sh. Usage: bash cpu_eval.sh NAME...
set -u
cd "$(dirname "$0")"
P="--tests perturbations --scenarios 1,2 --trials 50 --perturbations wind_gusts,water_current,motor_lag,action_latency,beam_dropout,mass"
for name in "$@"; do
  python -m docrl_jax.robustness --run runs/$name --label "$name" $P \
    --out eval/perturbations_$name > eval_perturbations_$name.log 2>&1
  echo "perturbations_$name rc=$?" >> eval_rc_cpu
done
