#!/usr/bin/env bash
# On this repository's 2-core CPU: the same perturbations as cpu_eval.sh in scenario 3 (50 trials), so
# that the goal perturbations are covered in all three scenarios. Usage: bash cpu_eval_s3.sh NAME...
set -u
cd "$(dirname "$0")"
P="--tests perturbations --scenarios 3 --trials 50 --perturbations wind_gusts,water_current,motor_lag,action_latency,beam_dropout,mass"
for name in "$@"; do
  python -m docrl_jax.robustness --run runs/$name --label "$name" $P \
    --out eval/perturbations_s3_$name > eval_perturbations_s3_$name.log 2>&1
  echo "perturbations_s3_$name rc=$?" >> eval_rc_cpu
done
