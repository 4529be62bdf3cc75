#!/usr/bin/env bash
# Issue 21: slant_beams 8 at 30 degrees, 3 more seeds (13-15), and the packaged recipe's committed seeds
# 10-12 evaluated on the same GPU. Runs from a copy of the tree (a later device call re-syncs the tree).
set -u
deadline=${1:-560}
R=/tmp/slant2; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs .diag /tmp/wt/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/slant2; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt
    ev() { name=$1; shift
      python3 -m docrl_jax.robustness "$@" --tests perturbations,random_trips,held_out_layouts \
        --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1; echo "$name rc=$?" >> $R/eval_rc; }
    ev rc100 --run .diag/rc100runs/gen_rc100_s10 --label "td3_lstm_generalist (reward_collide -100), seeds 10-12"
    python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=13 \
      --set name=gen_slant8e30_s13 --set env.slant_beams=8 --set env.slant_elevation_deg=30 --no-progress \
      --run-dir $R/runs/gen_slant8e30_s13 > $R/gen_slant8e30_s13.log 2>&1; echo "train rc=$?" >> $R/train_rc
    ev slant8e30_s13 --run $R/runs/gen_slant8e30_s13 --label "slant_beams 8 at 30 deg, seeds 13-15"
    echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
cat $R/train_rc $R/eval_rc 2>/dev/null; for f in $R/*.log; do echo "== $f"; tail -n 2 $f; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| (Paper|Random|Held)" $f | head -12; done
if [ -e $R/rc ]; then
  cp $R/gpu.txt $OUT/; bash benchmarks/pack_runs.sh $R/runs $OUT/slant2_runs.tgz
  (cd $R && tar czf $OUT/slant2_eval.tgz eval *.log train_rc eval_rc); echo DONE
fi
