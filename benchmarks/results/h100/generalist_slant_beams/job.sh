#!/usr/bin/env bash
# Issue 21: the generalist with slanted beam rings (env.slant_beams 8 at 30 / 20 degrees), 3 seeds vmapped,
# one after the other on one GPU, each then through pairs, trips and layouts; and the packaged recipe's
# committed seeds 10-12 (reward_collide -100) evaluated on the same GPU. Background; waits up to DEADLINE_S.
set -u
deadline=${1:-560}
R=/tmp/slant; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/slant
    tr() { name=$1; shift
      python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=10 \
        --set name=$name "$@" --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1; echo "$name rc=$?" >> $R/train_rc; }
    ev() { name=$1; shift
      python3 -m docrl_jax.robustness "$@" --tests perturbations,random_trips,held_out_layouts \
        --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1; echo "$name rc=$?" >> $R/eval_rc; }
    tr gen_slant8e30_s10 --set env.slant_beams=8 --set env.slant_elevation_deg=30
    ev slant8e30 --run $R/runs/gen_slant8e30_s10 --label "slant_beams 8 at 30 deg, seeds 10-12"
    ev rc100 --run .diag/rc100runs/gen_rc100_s10 --label "td3_lstm_generalist (reward_collide -100), seeds 10-12"
    tr gen_slant8e20_s10 --set env.slant_beams=8 --set env.slant_elevation_deg=20
    ev slant8e20 --run $R/runs/gen_slant8e20_s10 --label "slant_beams 8 at 20 deg, seeds 10-12"
    echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
cat $R/train_rc $R/eval_rc 2>/dev/null; for f in $R/*.log; do echo "== $f"; tail -n 2 $f; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| (Paper|Random|Held)" $f | head -12; done
if [ -e $R/rc ]; then
  cp $R/gpu.txt $OUT/; bash benchmarks/pack_runs.sh $R/runs $OUT/slant_runs.tgz
  (cd $R && tar czf $OUT/slant_eval.tgz eval *.log train_rc eval_rc); echo DONE
fi
