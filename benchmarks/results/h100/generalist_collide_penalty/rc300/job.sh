#!/usr/bin/env bash
# Issue 21: the generalist with reward_collide -300, 3 seeds vmapped on one GPU, then pairs, trips and
# layouts on that GPU. Background (outlives one device call); waits up to DEADLINE_S.
set -u
deadline=${1:-560}
R=/tmp/rc300; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/rc300
    python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=10 \
      --set env.reward_collide=-300 --set name=gen_rc300_s10 --no-progress --run-dir $R/runs/gen_rc300_s10 > $R/gen_rc300_s10.log 2>&1
    python3 -m docrl_jax.robustness --run $R/runs/gen_rc300_s10 --label "reward_collide -300, seeds 10-12" \
      --tests perturbations,random_trips,held_out_layouts --perturbations none --out $R/eval/rc300 > $R/eval_rc300.log 2>&1
    echo $? > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
for f in $R/*.log; do echo "== $f"; tail -n 2 $f; done
if [ -e $R/rc ]; then
  cp $R/gpu.txt $OUT/; bash benchmarks/pack_runs.sh $R/runs $OUT/rc300_runs.tgz
  (cd $R && tar czf $OUT/rc300_eval.tgz eval *.log); echo DONE
fi
