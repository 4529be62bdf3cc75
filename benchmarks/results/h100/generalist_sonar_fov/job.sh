#!/usr/bin/env bash
# Issue 21: the generalist with a wider sonar fan (env.sonar_fov_deg 180 / 270) against the packaged recipe,
# 3 seeds vmapped per GPU on a 4-GPU machine, then the robustness benchmark (pairs, trips, layouts) of the
# new runs and of the margin recipe's 7 committed seeds (.diag/runs), one command per GPU. Background
# (outlives one device call); waits up to DEADLINE_S, then returns what is done.
set -u
deadline=${1:-560}
R=/tmp/sonar; mkdir -p $R/runs $R/eval
if [ ! -e $R/started ]; then
  touch $R/started
  nvidia-smi --query-gpu=name --format=csv > $R/gpu.txt
  setsid nohup bash -c '
    R=/tmp/sonar
    tr() { gpu=$1 name=$2; shift 2
      CUDA_VISIBLE_DEVICES=$gpu python3 -m docrl_jax.train --config td3_lstm_generalist --set train.num_seeds=3 \
        --set name=$name "$@" --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1; echo "$name rc=$?" >> $R/train_rc; }
    tr 0 gen_base_s10 --set train.seed=10 &
    tr 1 gen_sonar180_s10 --set train.seed=10 --set env.sonar_fov_deg=180 &
    tr 2 gen_sonar270_s10 --set train.seed=10 --set env.sonar_fov_deg=270 &
    tr 3 gen_sonar270_s13 --set train.seed=13 --set env.sonar_fov_deg=270 &
    wait
    touch $R/trained
    ev() { gpu=$1 name=$2; shift 2
      CUDA_VISIBLE_DEVICES=$gpu python3 -m docrl_jax.robustness "$@" --tests perturbations,random_trips,held_out_layouts \
        --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1; echo "$name rc=$?" >> $R/eval_rc; }
    ev 0 old_margin --run .diag/runs/gen_cd07 .diag/runs/gen_cd07_s3 .diag/runs/gen_cm_seed6 --label "generalist (margin), 7 committed seeds" &
    ev 1 base --run $R/runs/gen_base_s10 --label "td3_lstm_generalist, seeds 10-12" &
    ev 2 sonar180 --run $R/runs/gen_sonar180_s10 --label "sonar_fov_deg 180, seeds 10-12" &
    ev 3 sonar270 --run $R/runs/gen_sonar270_s10 $R/runs/gen_sonar270_s13 --label "sonar_fov_deg 270, seeds 10-15" &
    wait
    echo 0 > $R/rc' >/dev/null 2>&1 &
fi
t0=$(date +%s)
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && [ ! -e $R/rc ]; do sleep 5; done
cat $R/train_rc $R/eval_rc 2>/dev/null; for f in $R/*.log; do echo "== $f"; tail -n 2 $f; done
if [ -e $R/rc ]; then
  cp $R/gpu.txt $OUT/; bash benchmarks/pack_runs.sh $R/runs $OUT/sonar_runs.tgz
  (cd $R && tar czf $OUT/sonar_eval.tgz eval *.log train_rc eval_rc); echo DONE
fi
