#!/usr/bin/env bash
# On this repository's 2-core CPU: the perturbations of scenarios 1-2 (50 trials) for the hull-margin 0.1
# seeds, as ../../h100/generalist_slant_progress/cpu_eval.sh ran them for the packaged recipe's seeds.
set -u
cd "$(dirname "$0")"
P="--tests perturbations --scenarios 1,2 --trials 50 --perturbations wind_gusts,water_current,motor_lag,action_latency,beam_dropout,mass"
python -m docrl_jax.robustness --run runs/gen_hull0.1_s10 --label "hull_margin 0.1, seeds 10-12" $P \
  --out eval/perturbations_hull0.1_s1_s2 > eval_perturbations_hull0.1_s1_s2.log 2>&1
echo "perturbations_hull0.1 rc=$?" >> eval_rc_cpu
