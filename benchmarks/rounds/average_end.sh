# The policy average's end rate: does a slower end (agent.policy_average_tau 0.0003 instead of
# the default 0.001; both fall from policy_average_tau_start 0.01) remove the late slides of the trained
# scenario's W-A score, and what do its final policies fly in scenarios 1-3?
#   B_ARGS="--set agent.policy_average_tau=0.0003" bash benchmarks/gpu_lanes.sh benchmarks/rounds/average_end.sh 540
# On a 4-GPU host. Lane 0, on GPUs 0 and 2: a sweep of the end rate (TAUS) over SWEEP_SEEDS seeds from FIRST,
# evaluated every chunk with training paused. The average never feeds training, so the rows of one
# seed train the same actor and differ only in the policy read from it: a paired comparison, free of
# the spread between seeds. Lanes 1 and 3 (GPUs 1 and 3): seed_batches.sh's side b on seeds FIRST.. and
# FIRST+SEEDS.., whose final policies the evaluator flies (a sweep keeps no policies).
LANES=${LANES:-"0 1 3"}
source benchmarks/rounds/seed_batches.sh
TAUS=${TAUS:-0.001,0.0003,0.0001}
SWEEP_SEEDS=${SWEEP_SEEDS:-6}
lane() {
  if (($1 == 0)); then
    echo "sweep start $(date +%s)" >> $R/times
    CUDA_VISIBLE_DEVICES=${SWEEP_GPUS:-0,2} python3 -m docrl_jax.sweep --config td3_lstm \
      --grid agent.policy_average_tau=$TAUS --seeds $SWEEP_SEEDS --set train.seed=$FIRST \
      --set train.eval_every=409600 --set train.eval_alongside=false ${EXTRA:-} --run-dir $R/sweep > $R/sweep.log 2>&1
    echo "sweep rc=$? $(date +%s)" >> $R/times
    (cd $R && tar czf pack/sweep.tgz sweep sweep.log)
  else
    seed_batch "$1"
  fi
}
