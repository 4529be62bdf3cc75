#!/usr/bin/env bash
# Issue 21: launch to end, one seed, empty compile cache, of the generalist with slanted beams and the
# progress term (new) and of the packaged recipe (old), back to back on one GPU.
set -u
deadline=${1:-560}
R=/tmp/gt; mkdir -p $R
if [ ! -e $R/started ]; then
  touch $R/started
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs /tmp/wt/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/gt; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt
    one() { name=$1; shift; t0=$(date +%s.%N)
      timeout 300 python3 -m docrl_jax.train --config td3_lstm_generalist "$@" --compile-cache $R/cc_$name \
        --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1; rc=$?
      echo "$name rc=$rc launch_to_end_s=$(python3 -c "print(round($(date +%s.%N)-$t0,1))")" >> $R/times; }
    one new --set env.slant_beams=8 --set env.slant_elevation_deg=30 --set env.progress_reward_scale=2.0
    one old
    echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 3; done
cat $R/gpu.txt $R/times 2>/dev/null; for f in $R/*.log; do echo "== $f"; grep -E "compil|first|start" $f | head -5 | cut -c1-200; tail -n 2 $f | cut -c1-250; done
cp $R/gpu.txt $R/times $R/*.log $OUT/ 2>/dev/null; for n in new old; do cp $R/runs/$n/metrics.csv $OUT/metrics_$n.csv 2>/dev/null; cp $R/runs/$n/startup.json $OUT/startup_$n.json 2>/dev/null; done
[ -e $R/rc ] && echo DONE
