#!/usr/bin/env bash
# Issue 21: env.hull_margin on the generalist recipe, 4 GPUs, one lane each (3 seeds vmapped per launch):
# 0.2 seeds 10-12, 0.2 seeds 13-15, 0.1 seeds 10-12, 0.3 seeds 10-12; each lane then evaluates its run
# (paper pairs, random trips, held-out layouts) on its GPU. Runs from a copy of the tree.
set -u
deadline=${1:-560}
R=/tmp/hull1; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs benchmarks /tmp/wt/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  cat > $R/lane.sh <<'LANE'
R=/tmp/hull1; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt CUDA_VISIBLE_DEVICES=$1; seed=$2; m=$3
name=gen_hull${m}_s$seed
python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=$seed \
  --set name=$name --set env.hull_margin=$m --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1
echo "$name rc=$?" >> $R/train_rc
python3 -m docrl_jax.robustness --run $R/runs/$name --label "hull_margin $m, seeds $seed-$((seed+2))" \
  --tests perturbations,random_trips,held_out_layouts --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1
echo "$name rc=$?" >> $R/eval_rc
touch $R/done_$1
LANE
  setsid nohup bash $R/lane.sh 0 10 0.2 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 1 13 0.2 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 2 10 0.1 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 3 10 0.3 >/dev/null 2>&1 &
fi
t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/gpu.txt $R/train_rc $R/eval_rc 2>/dev/null
for f in $R/gen*.log; do echo "== $f"; tail -n 2 $f | cut -c1-300; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| (Paper|Random|Held)" $f | head -12; done
cp $R/gpu.txt $OUT/ 2>/dev/null
(cd $R && tar czf $OUT/hull1_eval.tgz eval *.log train_rc eval_rc 2>/dev/null)
if alldone; then bash benchmarks/pack_runs.sh $R/runs $OUT/hull1_runs.tgz && echo DONE; fi
