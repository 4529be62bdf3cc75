# Final policies by the batch: two sides of td3_lstm, a and b, each trained as batches of
# SEEDS seeds in one launch (train.num_seeds: the seeds vmapped on one GPU, each with its own envs,
# buffer, agent and evaluations), then the evaluator (100 trials, scenarios 1-3) flies every seed's final
# policy and its best one. Many final policies per GPU-minute: a rate of bad final policies of a few in a
# hundred needs tens of seeds a side, which ten separate launches cannot show. Time to 90 % is not
# this job's figure (seeds sharing a GPU run slower); metrics.csv still gives each seed's env steps to it
# (benchmarks/updates_to_target.py).
#   A_ARGS="" B_ARGS="--set env.hull_margin=0.1" bash benchmarks/gpu_lanes.sh benchmarks/rounds/seed_batches.sh 540
# Lane N trains side a for even N and side b for odd N, on seeds FIRST + (N div 2) * SEEDS onwards, so
# lanes 0 and 1 train the same seeds, one per side (and lanes 2, 3 the next SEEDS). Every launch shares
# one compilation cache, empty when the job starts.
# SIDE_A and SIDE_B name the sides (default a and b; no underscore). NO_BEST=1 skips the best policies'
# evaluation. A CPU rehearsal shortens it: EXTRA (more train arguments, empty in the job), TRIALS, SEEDS,
# LANES.
LANES=${LANES:-"0 1 2 3"}
SEEDS=${SEEDS:-8}
FIRST=${FIRST:-5001}
export DOCRL_JAX_COMPILE_CACHE=$R/cache
EVAL="--trials ${TRIALS:-100} --scenarios 1,2,3"
seed_batch() {
  local side=${SIDE_A:-a} args=${A_ARGS:-}
  if (($1 % 2)); then side=${SIDE_B:-b} args=${B_ARGS:-}; fi
  # `batch`, not `name`: gpu_lanes' train and evaluator set a `name` of their own.
  local seed=$((FIRST + $1 / 2 * SEEDS)) batch
  batch=${side}_s$seed
  train $batch "td3_lstm $side seeds $seed+" --config td3_lstm --set train.seed=$seed --set train.num_seeds=$SEEDS \
    $args ${EXTRA:-}
  evaluator ${batch}_final "td3_lstm $side final" $R/runs/$batch -- --which final $EVAL
  [ -n "${NO_BEST:-}" ] || evaluator ${batch}_best "td3_lstm $side best" $R/runs/$batch -- --which best $EVAL
}
lane() { seed_batch "$1"; }
