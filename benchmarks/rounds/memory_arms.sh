# What memory buys in tanks a person builds (the memory table of docs/LEVELS.md), and the recipe's launch to end
# alone on its GPU: every arm is `sac_mlp_tanks` as packaged (route reward 2) with a memory change, each
# launch 3 vmapped seeds (0-2) at the recipe's 50 M env steps, then evaluated on its GPU, mapless, on the
# held-out structured tanks and the gallery. Lane 0 trains the recipe itself, alone on GPU 0, for its
# launch-to-end time; lanes 2 and 6 share GPU 2, the others are alone. After training, lanes 0, 1 and 3
# fly one seed each of `sac_mlp_generalist` (seeds 10-12 of its confirmation runs) route-guided on the
# same tanks.
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/memory_arms.sh            (PART=1: every lane)
#   PART=2 bash benchmarks/gpu_lanes.sh benchmarks/rounds/memory_arms.sh     (the lanes a lost machine cut off)
# PART=2 is what reruns when the machine went back after the first call: the launches that had ended
# (lanes 0 and 3) were packed; it evaluates lane 3's runs (unpacked into .jobs/old_runs/runs/stack4), reruns
# lanes 1 and 6 alone on their GPUs, and the LSTM whose critics see its carry (which had not learnt by
# 20 M env steps, train success 0.01) to 20 M env steps only, for its learning curve.
# Unpack runs/sac_mlp_gen_s10 of benchmarks/results/h200/generalist_confirm/raw.tar.gz into .jobs/old_runs
# (in git history: docs/results-archive.md has the command that brings it back).
PART=${PART:-1}
[ $PART = 1 ] && LANES=${LANES:-"0 1 2 3 6"} || LANES=${LANES:-"0 1 2 3"}
SEEDS="--set train.num_seeds=3 --set train.seed=0"
TANKS="--tests structured,tanks --trials 350 --layouts 1000"
GEN=$R/old_runs/sac_mlp_gen_s10
LSTM128="--set agent.actor=lstm --set agent.actor_hidden=[128] --set agent.memory=true --set replay.seq_len=32 --set replay.burn_in=8 --set replay.batch_size=512"
CARRY="--set agent.critic_carry=true"
arm() {  # arm NAME LABEL SETS...: train, then evaluate on the tanks
  name=$1 label=$2; shift 2
  train $name "$label" --config sac_mlp_tanks "$@" $SEEDS
  evaluate $name "$label" $R/runs/$name -- $TANKS
}
guided_generalist() {
  evaluate gen_guided_$1 "sac_mlp_generalist guided" $GEN -- --guide --which final --seed-index $1 $TANKS
}
lane() {
  if [ $PART = 2 ]; then
    case $1 in
    0) evaluate stack4 "sac_mlp_tanks, 4 stacked observations (actor and critics)" $R/old_runs/runs/stack4 -- $TANKS
       guided_generalist 0 ;;
    1) arm lstm128 "sac_mlp_tanks, LSTM(128) actor" $LSTM128 ;;
    2) arm stack8 "sac_mlp_tanks, 8 stacked observations (actor and critics)" --set agent.frames=8 $CARRY ;;
    3) train lstm128_carry "sac_mlp_tanks, LSTM(128) actor, critics see its carry, 20 M env steps" \
         --config sac_mlp_tanks $LSTM128 $CARRY $SEEDS --set train.total_env_steps=20000000
       guided_generalist 1
       guided_generalist 2 ;;
    esac
    return
  fi
  case $1 in
  0) train recipe "sac_mlp_tanks" --config sac_mlp_tanks $SEEDS
     guided_generalist 0 ;;
  1) arm lstm128 "sac_mlp_tanks, LSTM(128) actor" $LSTM128
     guided_generalist 1 ;;
  2) arm lstm128_carry "sac_mlp_tanks, LSTM(128) actor, critics see its carry" $LSTM128 $CARRY ;;
  3) arm stack4 "sac_mlp_tanks, 4 stacked observations (actor and critics)" --set agent.frames=4 $CARRY
     guided_generalist 2 ;;
  6) arm stack8 "sac_mlp_tanks, 8 stacked observations (actor and critics)" --set agent.frames=8 $CARRY ;;
  esac
}
