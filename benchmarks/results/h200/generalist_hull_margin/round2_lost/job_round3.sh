#!/usr/bin/env bash
# Issue 21, round 3 (one GPU, training only, evaluated on the CPU): env.hull_margin 0.1 seeds 13-15, then
# sac_lstm trained the generalist's way, seeds 10-12. Each run is packed as soon as it ends.
set -u
deadline=${1:-560}
R=/tmp/hull3; mkdir -p $R/runs $R/pack
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt3 && mkdir /tmp/wt3 && cp -r docrl_jax assets configs benchmarks /tmp/wt3/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  cat > $R/lane.sh <<'LANE'
R=/tmp/hull3; cd /tmp/wt3; export PYTHONPATH=/tmp/site:/tmp/wt3
tr() { name=$1; shift
  python3 -m docrl_jax.train "$@" --set train.num_seeds=3 --set name=$name --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1
  echo "$name rc=$?" >> $R/train_rc
  mkdir -p $R/one_$name && mv $R/runs/$name $R/one_$name/ && bash benchmarks/pack_runs.sh $R/one_$name $R/pack/$name.tgz
  cp $R/$name.log $R/pack/; touch $R/done_$name; }
GEN="$(python3 benchmarks/generalist_sets.py)"
tr gen_hull0.1_s13 --config td3_lstm_generalist --set train.seed=13 --set env.hull_margin=0.1
tr sac_lstm_gen_s10 --config sac_lstm $GEN --set train.seed=10
LANE
  setsid nohup bash $R/lane.sh >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/done_sac_lstm_gen_s10 ]; do sleep 3; done
cat $R/gpu.txt $R/train_rc 2>/dev/null
for f in $R/*.log; do echo "== $f"; tail -n 1 $f | cut -c1-200; done
cp $R/gpu.txt $R/pack/* $OUT/ 2>/dev/null; ls $OUT
