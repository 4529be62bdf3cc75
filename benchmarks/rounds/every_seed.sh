# Every seed, every time: the packaged default as a user launches it, ten times, on seeds
# nobody tuned on (4701-4710), each its own launch of the README's command with only its seed and run
# directory set, one launch per GPU at a time on a 4-GPU host (lane N: seeds 4701+N, 4705+N, 4709+N
# up to 4710, one after the other: 3, 3, 2, 2). Every launch shares one persistent compilation cache,
# empty when the job starts, so each lane's first launch (4701-4704, the four at once) compiles and
# the later ones load (startup.json's `programs` says which each did). After each training, the
# evaluator (100 trials, scenarios 1-3) flies the run's final policy and its best one (the in-training
# evaluation's pick, train.track_best_policy) on its own trials.
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/every_seed.sh [DEADLINE_S]
#   python3 benchmarks/every_seed_table.py round_every_seed.tar        (here, the table)
# gpu_lanes' train adds --set name=NAME (a label; no program or result depends on it) and --no-progress.
# Old beside new on one host: SIDES="new old" (OLD_ARGS: the old side's overrides, e.g. --set
# agent.policy_average_tau_start=0) gives each seed an old launch too, stopped at 90 % (gpu_lanes'
# `target`: a time to 90 % without an end or evaluations), named old_sSEED and run before or after the
# new one in turn, so neither side always goes first. NEW_ARGS: the new side's own overrides (e.g. a
# candidate default, --set agent.gamma=0.995, beside the packaged one on the old side). LANES sets the lanes (N lanes: seeds FIRST+lane, +N, ...);
# FIRST (default 4701) the first of the ten seeds, so a later job can fly ten seeds no earlier job saw;
# COUNT (default 10) how many, so a job a lost machine cut off can go on from the seed it had not begun;
# WHICH (default "final best") the policies the evaluator flies (final alone where device time is short:
# a checkpoint's metadata says whether the run's best evaluation was its last).
# A CPU rehearsal shortens it: EXTRA (more train arguments, empty in the job), TRIALS, LANES.
LANES=${LANES:-"0 1 2 3"}
export DOCRL_JAX_COMPILE_CACHE=$R/cache
EVAL="--trials ${TRIALS:-100} --scenarios 1,2,3"
new_side() {
  train s$1 "td3_lstm seed $1" --config td3_lstm --set train.seed=$1 ${NEW_ARGS:-} ${EXTRA:-}
  for which in ${WHICH:-final best}; do
    evaluator s${1}_$which "td3_lstm seed $1 $which" $R/runs/s$1 -- --which $which $EVAL
  done
}
old_side() { target old_s$1 "td3_lstm seed $1 old" $1 --config td3_lstm ${OLD_ARGS:-} ${EXTRA:-}; }
lane() {
  local lanes=$(echo $LANES | wc -w) turn=0
  local first=${FIRST:-4701}
  for ((seed = first + $1; seed < first + ${COUNT:-10}; seed += lanes)); do
    case " ${SIDES:-new} " in
      *" old "*) if ((turn++ % 2)); then old_side $seed; new_side $seed; else new_side $seed; old_side $seed; fi;;
      *) new_side $seed;;
    esac
  done
}
