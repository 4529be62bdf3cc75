#!/usr/bin/env bash
# Issue 21: six more seeds (16-21) of slant 8 at 30 deg with the progress term at 2, training only
# (evaluated on the CPU). Reuses slant3's copy of the tree.
set -u
deadline=${1:-560}
R=/tmp/slant4; mkdir -p $R/runs
if [ ! -e $R/started ]; then
  touch $R/started
  cat > $R/lane.sh <<'LANE'
R=/tmp/slant4; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt CUDA_VISIBLE_DEVICES=$1; seed=$2
while [ ! -e /tmp/slant3/done_$1 ]; do sleep 2; done
name=gen_slant8e30_prog2_s$seed
python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=$seed \
  --set name=$name --set env.slant_beams=8 --set env.slant_elevation_deg=30 --set env.progress_reward_scale=2.0 \
  --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1; echo "$name rc=$?" >> $R/train_rc
touch $R/done_$1
LANE
  setsid nohup bash $R/lane.sh 0 16 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 1 19 >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! { [ -e $R/done_0 ] && [ -e $R/done_1 ]; }; do sleep 3; done
cat /tmp/slant3/eval_rc $R/train_rc 2>/dev/null
for f in $R/*.log /tmp/slant3/eval_slant8e30_prog2_s13.log; do echo "== $f"; tail -n 2 $f | cut -c1-300; done
grep -E "^\| (Random|Held)" /tmp/slant3/eval/slant8e30_prog2_s13/robustness.md | head -4
(cd /tmp/slant3 && tar czf $OUT/slant3_eval.tgz eval *.log train_rc eval_rc 2>/dev/null)
bash benchmarks/pack_runs.sh /tmp/slant3/runs $OUT/slant3_runs.tgz
[ -e $R/done_0 ] && [ -e $R/done_1 ] && bash benchmarks/pack_runs.sh $R/runs $OUT/slant4_runs.tgz && (cd $R && tar czf $OUT/slant4_logs.tgz *.log train_rc) && echo DONE
