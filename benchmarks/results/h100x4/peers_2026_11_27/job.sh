#!/usr/bin/env bash
# Issue 22: the peer table refreshed, and our 5-seed time to 90 %, on one 4-GPU host, all at once.
# GPU 0 first runs ours (td3_lstm to its end, 5 seeds, seed 0 with an empty compile cache, then the
# evaluator on the five final policies; sac_lstm stopped at 90 %, 5 seeds), then joins the others.
# GPUs 1-3 take Brax runs from one queue, one run per GPU at a time, seed-major so that a cut-off
# round still has every configuration. Every job is packed the moment it ends.
#   bash .jobs/r22.sh DEADLINE_S     (again in the next call: the lanes keep running)
set -u
deadline=${1:-560}
R=/tmp/r22; mkdir -p $R/res $R/pack
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site .whl/*.whl
  rm -rf /tmp/wt && mkdir /tmp/wt && cp -r docrl_jax assets configs benchmarks /tmp/wt/
  nvidia-smi --query-gpu=name,driver_version --format=csv > $R/pack/gpu.txt
  python3 -c "import jax, jaxlib, brax; print('jax', jax.__version__, 'jaxlib', jaxlib.__version__, 'brax', brax.__version__)" >> $R/pack/gpu.txt 2>&1
  B="--budget-s 150 --grace-s 30 --out $R/res"
  : > $R/queue
  for s in 0 1 2; do
    echo "ppo_ant_s$s|--trainers ppo --seeds $s $B --tag ppo_ant_s$s" >> $R/queue
    echo "ppo_loco_s$s|--trainers ppo --recipe playground_locomotion --seeds $s $B --tag ppo_loco_s$s" >> $R/queue
    echo "ppo_dmc_s$s|--trainers ppo --recipe playground_dm_control --seeds $s $B --tag ppo_dmc_s$s" >> $R/queue
    echo "ppo_e8192_s$s|--trainers ppo --set ppo.num_envs=8192 --seeds $s $B --tag ppo_e8192_s$s" >> $R/queue
    echo "sac_dmc_s$s|--trainers sac --recipe playground_dm_control --seeds $s $B --tag sac_dmc_s$s" >> $R/queue
  done
  for s in 0 1 2; do
    echo "sac_ant_s$s|--trainers sac --seeds $s $B --tag sac_ant_s$s" >> $R/queue
  done
  cat > $R/lane.sh <<'LANE'
R=/tmp/r22; cd /tmp/wt; export PYTHONPATH=/tmp/site:/tmp/wt CUDA_VISIBLE_DEVICES=$1
stamp() { echo "$1 $2 gpu$3 $(date +%s)" >> $R/times; }
if [ "$1" = 0 ]; then
  stamp ours_td3 start 0
  python3 benchmarks/time_to_success.py --config td3_lstm --seeds 0 1 2 3 4 --to-end --budget-s 200 \
    --compile-cache warm --tag td3_lstm --run-root $R/runs_td3 --out $R/res > $R/ours_td3.log 2>&1
  stamp ours_td3 "end rc=$?" 0
  bash benchmarks/pack_runs.sh $R/runs_td3 $R/pack/runs_td3.tgz
  python3 -m docrl_jax.evaluate --run $R/runs_td3/td3_lstm_seed* --trials 100 --scenarios 1,2,3 \
    --label "td3_lstm, seeds 0-4" --out $R/res/eval_td3 > $R/eval_td3.log 2>&1
  stamp eval_td3 "end rc=$?" 0
  (cd $R && tar czf pack/ours_td3.tgz res/time_to_success_td3_lstm* res/eval_td3 ours_td3.log eval_td3.log)
  python3 benchmarks/time_to_success.py --config sac_lstm --seeds 0 1 2 3 4 --budget-s 150 \
    --compile-cache warm --tag sac_lstm --run-root $R/runs_sac --out $R/res > $R/ours_sac.log 2>&1
  stamp ours_sac "end rc=$?" 0
  (cd $R && tar czf pack/ours_sac.tgz res/time_to_success_sac_lstm* ours_sac.log)
fi
while :; do
  line=$(flock $R/queue.lock sh -c "head -n 1 $R/queue; sed -i 1d $R/queue")
  [ -z "$line" ] && break
  name=${line%%|*}; args=${line#*|}
  stamp $name start $1
  python3 benchmarks/peers.py $args > $R/$name.log 2>&1
  stamp $name "end rc=$?" $1
  (cd $R && tar czf pack/$name.tgz res/peers_$name* $name.log)
done
touch $R/lane_done_$1
LANE
  for g in 0 1 2 3; do setsid nohup bash $R/lane.sh $g >/dev/null 2>&1 & done
fi
t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/lane_done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/pack/gpu.txt $R/times 2>/dev/null
echo "queue left: $(wc -l < $R/queue)"
grep -h "both ways at\|not reached" $R/*.log 2>/dev/null | cut -c1-200
grep -h "median" $R/ours_*.log 2>/dev/null | tail -4
cp $R/times $R/pack/ 2>/dev/null; (cd $R && tar cf $OUT/r22_pack.tar pack)
alldone && echo ALL_DONE
