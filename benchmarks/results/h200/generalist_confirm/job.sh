#!/usr/bin/env bash
# Issue 21, confirmation round on 4 GPUs of one host, one lane per GPU, 3 vmapped seeds per launch,
# each launch evaluated on its GPU right after it trains; every run and evaluation is packed the
# moment it ends (so a deadline never loses one). Lanes:
#   GPU0: td3_lstm_generalist (hull margin 0.1) seeds 13-15, then the same with replay.batch_size=2048
#   GPU1: the same with env.hull_margin=0 (the config before) seeds 13-15, then the config seeds 16-18
#   GPU2: sac_lstm then sac_mlp trained the generalist's way (benchmarks/generalist_sets.py), seeds 10-12
#   GPU3: ddpg_mlp the generalist's way (100 M env steps) seeds 10-12, then td3_lstm (today's default) seeds 0-2
set -u
deadline=${1:-540}
R=/tmp/r21; mkdir -p $R/runs $R/eval $R/pack
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs benchmarks /tmp/wt/
  nvidia-smi --query-gpu=name,driver_version --format=csv > $R/pack/gpu.txt
  python3 -c "import jax, jaxlib; print('jax', jax.__version__, 'jaxlib', jaxlib.__version__)" >> $R/pack/gpu.txt 2>&1
  cat > $R/lane.sh <<'LANE'
R=/tmp/r21; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt CUDA_VISIBLE_DEVICES=$1
GEN="$(python3 benchmarks/generalist_sets.py)"
job() { name=$1; label=$2; shift 2
  echo "$name start $(date +%s)" >> $R/times
  python3 -m docrl_jax.train "$@" --set train.num_seeds=3 --set name=$name --no-progress --run-dir $R/runs/$name > $R/$name.log 2>&1
  echo "$name train rc=$? $(date +%s)" >> $R/times
  mkdir -p $R/one_$name && cp -r $R/runs/$name $R/one_$name/ && bash benchmarks/pack_runs.sh $R/one_$name $R/pack/runs_$name.tgz
  python3 -m docrl_jax.robustness --run $R/runs/$name --label "$label" \
    --tests perturbations,random_trips,held_out_layouts --perturbations none --out $R/eval/$name > $R/eval_$name.log 2>&1
  echo "$name eval rc=$? $(date +%s)" >> $R/times
  (cd $R && tar czf pack/eval_$name.tgz eval/$name $name.log eval_$name.log); }
case $1 in
0) job gen_s13 "td3_lstm_generalist, seeds 13-15" --config td3_lstm_generalist --set train.seed=13
   job gen_b2048_s13 "td3_lstm_generalist batch 2048, seeds 13-15" --config td3_lstm_generalist --set train.seed=13 --set replay.batch_size=2048 ;;
1) job gen_hull0_s13 "td3_lstm_generalist hull_margin 0, seeds 13-15" --config td3_lstm_generalist --set train.seed=13 --set env.hull_margin=0
   job gen_s16 "td3_lstm_generalist, seeds 16-18" --config td3_lstm_generalist --set train.seed=16 ;;
2) job sac_lstm_gen_s10 "sac_lstm generalist's way, seeds 10-12" --config sac_lstm $GEN --set train.seed=10
   job sac_mlp_gen_s10 "sac_mlp generalist's way, seeds 10-12" --config sac_mlp $GEN --set train.seed=10 ;;
3) job ddpg_mlp_gen_s10 "ddpg_mlp generalist's way (100 M), seeds 10-12" --config ddpg_mlp $GEN --set train.seed=10 --set train.total_env_steps=100000000
   job td3_lstm_s0 "td3_lstm, seeds 0-2" --config td3_lstm --set train.seed=0 ;;
esac
touch $R/lane_done_$1
LANE
  for g in 0 1 2 3; do setsid nohup bash $R/lane.sh $g >/dev/null 2>&1 & done
fi
t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/lane_done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/pack/gpu.txt $R/times 2>/dev/null
for f in $R/*.log; do echo "== $(basename $f): $(tail -n 1 $f | cut -c1-220)"; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| (Paper|Random|Held)" $f | head -12; done
cp $R/times $R/pack/ 2>/dev/null; cp $R/pack/* $OUT/ 2>/dev/null; ls $OUT
alldone && echo ALL_DONE
