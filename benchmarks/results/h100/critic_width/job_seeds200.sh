#!/usr/bin/env bash
# Issue 22: is a narrower critic as sample-efficient? Eight seeds vmapped per variant (updates to 90 %),
# then the update's cost per variant. Background; waits up to DEADLINE_S, returns what is done.
set -u
deadline=${1:-560}
R=/tmp/cw22b; mkdir -p $R/runs
if [ ! -e $R/started ]; then
  touch $R/started
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/cw22b
    run() { name=$1; shift
      timeout -s INT 170 python3 -m docrl_jax.train --config td3_lstm --no-progress --set train.num_seeds=8 \
        --set train.seed=200 --set name=$name --run-dir $R/runs/$name "$@" > $R/$name.log 2>&1; }
    run base
    run c256 --set "agent.critic_hidden=[256,256]"
    python3 benchmarks/updates_to_target.py $R/runs/base $R/runs/c256  > $R/utt.md 2>&1
    echo $? > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
for f in $R/*.log; do echo "== $f"; tail -n 3 $f; done
if [ -e $R/rc ]; then
  cat $R/utt.md; cat $R/update_cost.log | tail -15
  cp $R/gpu.txt $R/utt.md $OUT/; (cd $R && tar czf $OUT/cw22b.tgz *.log utt.md gpu.txt)
  bash benchmarks/pack_runs.sh $R/runs $OUT/cw22b_runs.tgz; echo DONE
fi
