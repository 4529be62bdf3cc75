#!/usr/bin/env bash
# Issue 21, round 2, 4 GPUs, training only (evaluated on the CPU): env.hull_margin 0.1 seeds 13-15 and
# 16-18; the memory table with the packaged generalist env: sac_lstm and sac_mlp, seeds 10-12.
set -u
deadline=${1:-560}
R=/tmp/hull2; mkdir -p $R/runs
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt2 && mkdir /tmp/wt2 && cp -r docrl_jax assets configs benchmarks /tmp/wt2/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  cat > $R/lane.sh <<'LANE'
R=/tmp/hull2; cd /tmp/wt2; export PYTHONPATH=/tmp/site:/tmp/wt2 CUDA_VISIBLE_DEVICES=$1; name=$2; shift 2
python3 -m docrl_jax.train "$@" --set train.num_seeds=3 --set name=$name --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1
echo "$name rc=$?" >> $R/train_rc
touch $R/done_$1
LANE
  GEN="$(PYTHONPATH=/tmp/site:/tmp/wt2 python3 /tmp/wt2/benchmarks/generalist_sets.py)"
  setsid nohup bash $R/lane.sh 0 gen_hull0.1_s13 --config td3_lstm_generalist --set train.seed=13 --set env.hull_margin=0.1 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 1 gen_hull0.1_s16 --config td3_lstm_generalist --set train.seed=16 --set env.hull_margin=0.1 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 2 sac_lstm_gen_s10 --config sac_lstm $GEN --set train.seed=10 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 3 sac_mlp_gen_s10 --config sac_mlp $GEN --set train.seed=10 >/dev/null 2>&1 &
fi
t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/gpu.txt $R/train_rc 2>/dev/null
for f in $R/*.log; do echo "== $f"; tail -n 2 $f | cut -c1-300; done
cp $R/gpu.txt $OUT/ 2>/dev/null
(cd $R && tar czf $OUT/hull2_logs.tgz *.log train_rc 2>/dev/null)
if alldone; then bash benchmarks/pack_runs.sh $R/runs $OUT/hull2_runs.tgz && echo DONE; fi
