#!/usr/bin/env bash
# Issue 22: the code when the issue was filed (.old = 92761bc) against main, side by side on one
# 4-GPU host, one lane per GPU, each lane alone on its GPU:
#   GPU0: main, time to 90 % of the default command, seeds 0-4 (seed 0 with an empty compile cache)
#   GPU1: the same with the old code
#   GPU2: start-up, launch by launch, versions interleaved (ab_startup.py, 2 rounds x (1 cold + 2 warm))
#   GPU3: trainer throughput at 4,096 envs, old then new, each tree's own script and default config
set -u
deadline=${1:-540}
R=/tmp/r22b; mkdir -p $R/res $R/pack
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs benchmarks .old /tmp/wt/
  (cd /tmp/wt && python3 -m compileall -q docrl_jax .old/docrl_jax >/dev/null)   # as a pip install does
  nvidia-smi --query-gpu=name,driver_version --format=csv > $R/pack/gpu.txt
  cat > $R/lane.sh <<'LANE'
R=/tmp/r22b; cd /tmp/wt; export PYTHONPATH=/tmp/site CUDA_VISIBLE_DEVICES=$1
stamp() { echo "$1 $2 gpu$3 $(date +%s)" >> $R/times; }
case $1 in
0) stamp new_ttt start 0
   PYTHONPATH=/tmp/site:/tmp/wt python3 benchmarks/time_to_success.py --config td3_lstm --seeds 0 1 2 3 4 --budget-s 150 \
     --compile-cache warm --tag new --run-root $R/runs_new --out $R/res > $R/new_ttt.log 2>&1
   stamp new_ttt "end rc=$?" 0 ;;
1) stamp old_ttt start 1
   cd /tmp/wt/.old && PYTHONPATH=/tmp/site:/tmp/wt/.old python3 benchmarks/time_to_success.py --config td3_lstm --seeds 0 1 2 3 4 \
     --budget-s 150 --compile-cache warm --tag old --run-root $R/runs_old --out $R/res > $R/old_ttt.log 2>&1
   stamp old_ttt "end rc=$?" 1 ;;
2) stamp ab_startup start 2
   python3 benchmarks/ab_startup.py --rounds 2 --warm 2 --out $R/res/ab_startup > $R/ab_startup.log 2>&1
   stamp ab_startup "end rc=$?" 2 ;;
3) stamp tp_old start 3
   cd /tmp/wt/.old && PYTHONPATH=/tmp/site:/tmp/wt/.old python3 benchmarks/train_throughput.py --configs td3_lstm --num-envs 4096 \
     --iters 50 --repeats 5 --out $R/res --stem train_throughput_old > $R/tp_old.log 2>&1
   stamp tp_old "end rc=$?" 3
   cd /tmp/wt && PYTHONPATH=/tmp/site:/tmp/wt python3 benchmarks/train_throughput.py --configs td3_lstm --num-envs 4096 \
     --iters 50 --repeats 5 --out $R/res --stem train_throughput_new > $R/tp_new.log 2>&1
   stamp tp_new "end rc=$?" 3 ;;
esac
touch $R/lane_done_$1
LANE
  for g in 0 1 2 3; do setsid nohup bash $R/lane.sh $g >/dev/null 2>&1 & done
fi
t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/lane_done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/pack/gpu.txt $R/times 2>/dev/null
grep -h "both ways at\|not reached\|Median" $R/*_ttt.log 2>/dev/null | cut -c1-200
tail -n 12 $R/ab_startup.log; tail -n 4 $R/tp_*.log
cp $R/times $R/pack/ 2>/dev/null
(cd $R && tar czf $OUT/r22b.tgz pack res *.log)
alldone && echo ALL_DONE
