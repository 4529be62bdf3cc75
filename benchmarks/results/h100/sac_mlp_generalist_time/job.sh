#!/usr/bin/env bash
# Issue 21: launch to end of the packaged sac_mlp_generalist, one seed per launch, on one H100:
# seeds 20, 21, 22 in turn, one compilation cache (the first launch compiles, the others load).
set -u
deadline=${1:-500}
R=/tmp/st; mkdir -p $R/runs
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs benchmarks /tmp/wt/
  nvidia-smi --query-gpu=name,driver_version --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/st; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt
    for s in 20 21 22; do t0=$(date +%s.%N)
      timeout 400 python3 -m docrl_jax.train --config sac_mlp_generalist --set train.seed=$s --compile-cache $R/cc \
        --no-progress --run-dir $R/runs/smg_s$s > $R/smg_s$s.log 2>&1; rc=$?
      echo "smg_s$s rc=$rc launch_to_end_s=$(python3 -c "print(round($(date +%s.%N)-$t0,1))")" >> $R/times
    done; echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 3; done
cat $R/gpu.txt $R/times 2>/dev/null; for f in $R/*.log; do echo "== $f"; tail -n 2 $f | cut -c1-250; done
mkdir -p $R/pack; cp $R/gpu.txt $R/times $R/*.log $R/pack/ 2>/dev/null
for d in $R/runs/*/; do n=$(basename $d); cp $d/metrics.csv $R/pack/metrics_$n.csv 2>/dev/null; cp $d/startup.json $R/pack/startup_$n.json 2>/dev/null; done
tar cf $OUT/smg_time.tar -C $R pack
[ -e $R/rc ] && echo DONE
