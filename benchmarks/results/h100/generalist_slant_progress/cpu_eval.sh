#!/usr/bin/env bash
# On this repository's 2-core CPU: seeds 16-21 (trained in job2.sh) through the same tests as the GPU
# evaluation, then the perturbations of scenarios 1-2 (50 trials) for the progress-term and -30 seeds.
set -u
ev() { name=$1; shift
  python -m docrl_jax.robustness "$@" --out eval/$name > eval_$name.log 2>&1; echo "$name rc=$?" >> eval_rc_cpu; }
for s in 16 19; do
  ev slant8e30_prog2_s$s --run runs/gen_slant8e30_prog2_s$s --label "slant 8 at 30 deg, progress term 2, seeds $s-$((s+2))" \
    --tests perturbations,random_trips,held_out_layouts --perturbations none
done
P="--tests perturbations --scenarios 1,2 --trials 50 --perturbations wind_gusts,water_current,motor_lag,action_latency,beam_dropout,mass"
ev perturbations_prog2_s1_s2 --run runs/gen_slant8e30_prog2_s10 --label "slant 8 at 30 deg, progress term 2, seeds 10-12" \
  --run runs/gen_slant8e30_prog2_s13 --label "slant 8 at 30 deg, progress term 2, seeds 13-15" $P
ev perturbations_rc30_s1_s2 --run runs/gen_slant8e30_rc30_s10 --label "slant 8 at 30 deg, reward_collide -30, seeds 10-12" \
  --run runs/gen_slant8e30_rc30_s13 --label "slant 8 at 30 deg, reward_collide -30, seeds 13-15" $P
