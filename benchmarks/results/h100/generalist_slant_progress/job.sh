#!/usr/bin/env bash
# Issue 21: slanted beams (8 at 30 deg) without the time-out basin. Two GPUs, each: round A
# (reward_collide -30) then round B (reward_collide -100 with the progress term at 2), 3 seeds vmapped
# per launch; GPU 1 also evaluates the packaged recipe's committed seeds 10-12 on the same machine.
# Runs from a copy of the tree (a later device call re-syncs the tree).
set -u
deadline=${1:-560}
R=/tmp/slant3; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs .diag /tmp/wt/
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  cat > $R/lane.sh <<'LANE'
R=/tmp/slant3; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt CUDA_VISIBLE_DEVICES=$1; seed=$2; base=$3
ev() { name=$1; shift
  python3 -m docrl_jax.robustness "$@" --tests perturbations,random_trips,held_out_layouts \
    --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1; echo "$name rc=$?" >> $R/eval_rc; }
tr() { name=$1; shift
  python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 --set train.seed=$seed \
    --set name=$name --set env.slant_beams=8 --set env.slant_elevation_deg=30 "$@" --no-progress \
    --run-dir $R/runs/$name > $R/$name.log 2>&1; echo "$name rc=$?" >> $R/train_rc; }
tr gen_slant8e30_rc30_s$seed --set env.reward_collide=-30
ev slant8e30_rc30_s$seed --run $R/runs/gen_slant8e30_rc30_s$seed --label "slant 8 at 30 deg, reward_collide -30, seeds $seed-$((seed+2))"
[ "$base" = 1 ] && ev rc100 --run .diag/rc100runs/gen_rc100_s10 --label "td3_lstm_generalist (reward_collide -100), seeds 10-12"
touch $R/A_done_$1
tr gen_slant8e30_prog2_s$seed --set env.progress_reward_scale=2.0
ev slant8e30_prog2_s$seed --run $R/runs/gen_slant8e30_prog2_s$seed --label "slant 8 at 30 deg, progress term 2, seeds $seed-$((seed+2))"
touch $R/done_$1
LANE
  setsid nohup bash $R/lane.sh 0 10 0 >/dev/null 2>&1 &
  setsid nohup bash $R/lane.sh 1 13 1 >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! { [ -e $R/done_0 ] && [ -e $R/done_1 ]; }; do sleep 5; done
cat $R/gpu.txt $R/train_rc $R/eval_rc 2>/dev/null
for f in $R/*.log; do echo "== $f"; tail -n 2 $f | cut -c1-300; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| (Paper|Random|Held)" $f | head -12; done
cp $R/gpu.txt $OUT/ 2>/dev/null
(cd $R && tar czf $OUT/slant3_eval.tgz eval *.log train_rc eval_rc 2>/dev/null)
if [ -e $R/A_done_0 ] && [ -e $R/A_done_1 ]; then bash benchmarks/pack_runs.sh $R/runs $OUT/slant3_runs.tgz; fi
[ -e $R/done_0 ] && [ -e $R/done_1 ] && echo DONE
