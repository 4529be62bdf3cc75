# Every seed, every time (issue 47): the packaged default as a user launches it, ten times, on seeds
# nobody tuned on (4701-4710), each its own launch of the README's command with only its seed and run
# directory set, one launch per GPU at a time on a 4-GPU host (lane N: seeds 4701+N, 4705+N, 4709+N
# up to 4710, one after the other: 3, 3, 2, 2). Every launch shares one persistent compilation cache,
# empty when the round starts, so each lane's first launch (4701-4704, the four at once) compiles and
# the later ones load (startup.json's `programs` says which each did). After each training, the
# evaluator (100 trials, scenarios 1-3) flies the run's final policy and its best one (the in-training
# evaluation's pick, train.track_best_policy) on its own trials.
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/every_seed.sh [DEADLINE_S]
#   python3 benchmarks/every_seed_table.py round_every_seed.tar        (here, the table)
# gpu_lanes' train adds --set name=NAME (a label; no program or result depends on it) and --no-progress.
# A CPU rehearsal shortens it: EXTRA (more train arguments, empty in the round), TRIALS, LANES.
LANES=${LANES:-"0 1 2 3"}
export DOCRL_JAX_COMPILE_CACHE=$R/cache
EVAL="--trials ${TRIALS:-100} --scenarios 1,2,3"
lane() {
  for ((seed = 4701 + $1; seed <= 4710; seed += 4)); do
    train s$seed "td3_lstm seed $seed" --config td3_lstm --set train.seed=$seed ${EXTRA:-}
    evaluator s${seed}_final "td3_lstm seed $seed final" $R/runs/s$seed -- --which final $EVAL
    evaluator s${seed}_best "td3_lstm seed $seed best" $R/runs/s$seed -- --which best $EVAL
  done
}
