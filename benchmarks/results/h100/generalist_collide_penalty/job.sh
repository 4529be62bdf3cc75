#!/usr/bin/env bash
# Issue 21: the generalist with a larger collision penalty (env.reward_collide -30 / -100) or a 0.3 m
# collision margin against the packaged recipe, 3 seeds vmapped per GPU on a 4-GPU machine, then the
# robustness benchmark (pairs, trips, layouts) of each, one command per GPU. Background
# (outlives one device call); waits up to DEADLINE_S, then returns what is done.
set -u
deadline=${1:-560}
R=/tmp/rc; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/rc
    tr() { gpu=$1 name=$2; shift 2
      CUDA_VISIBLE_DEVICES=$gpu python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 \
        --set name=$name "$@" --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1; echo "$name rc=$?" >> $R/train_rc; }
    tr 0 gen_base_s10 --set train.seed=10 &
    tr 1 gen_rc30_s10 --set train.seed=10 --set env.reward_collide=-30 &
    tr 2 gen_rc100_s10 --set train.seed=10 --set env.reward_collide=-100 &
    tr 3 gen_cm03_s10 --set train.seed=10 --set env.collision_margin=0.3 --set env.goal_clearance=0.9 &
    wait
    touch $R/trained
    ev() { gpu=$1 name=$2; shift 2
      CUDA_VISIBLE_DEVICES=$gpu python3 -m docrl_jax.robustness "$@" --tests perturbations,random_trips,held_out_layouts \
        --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1; echo "$name rc=$?" >> $R/eval_rc; }
    ev 0 base --run $R/runs/gen_base_s10 --label "td3_lstm_generalist, seeds 10-12" &
    ev 1 rc30 --run $R/runs/gen_rc30_s10 --label "reward_collide -30, seeds 10-12" &
    ev 2 rc100 --run $R/runs/gen_rc100_s10 --label "reward_collide -100, seeds 10-12" &
    ev 3 cm03 --run $R/runs/gen_cm03_s10 --label "collision_margin 0.3, seeds 10-12" &
    wait
    echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
cat $R/train_rc $R/eval_rc 2>/dev/null; for f in $R/*.log; do echo "== $f"; tail -n 2 $f; done
if [ -e $R/rc ]; then
  cp $R/gpu.txt $OUT/; bash benchmarks/pack_runs.sh $R/runs $OUT/rc_runs.tgz
  (cd $R && tar czf $OUT/rc_eval.tgz eval *.log train_rc eval_rc); echo DONE
fi
