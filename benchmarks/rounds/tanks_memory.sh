# Tanks a person builds, 3 seeds per launch (docs/LEVELS.md, "Results"): the level-pool recipe against
# uniform sampling, its memory arms (TD3 with LSTM(32), SAC and TD3 with LSTM(128) over 24-step sequences)
# and its reward arms (the route-field reward beside, or instead of, the straight-line progress term, which
# makes every dead end a trap), on one 4-GPU host, two launches per GPU, every launch 3 vmapped seeds at the
# recipe's 50 M env steps; each evaluated on its GPU on the held-out structured tanks and the gallery (the
# two packaged recipes also on the held-out procedural layouts, random trips and the paper pairs).
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/tanks_memory.sh
# The generalists' policies come from their own runs: unpack runs/sac_mlp_gen_s10 and runs/gen_s13 of
# benchmarks/results/h200/generalist_confirm/raw.tar.gz (in git history: docs/results-archive.md) into
# .jobs/old_runs; OLD=0 leaves them out.
# Since this comparison, sac_mlp_tanks has route_reward 2 (the arm `route`): the other arms set it to 0.
LANES="0 1 2 3 4 5 6 7"
SEEDS="--set train.num_seeds=3 --set train.seed=0"
NOROUTE="--set levels.route_reward=0.0"
FULL="--tests perturbations,random_trips,held_out_layouts,structured,tanks --perturbations none --trials 350 --layouts 1000"
TANKS="--tests structured,tanks --trials 350 --layouts 1000"
LSTM128="--set agent.actor=lstm --set agent.actor_hidden=[128] --set agent.memory=true --set replay.seq_len=32 --set replay.burn_in=8 --set replay.batch_size=512"
lane() {
  case $1 in
  0) train tanks "sac_mlp_tanks" --config sac_mlp_tanks $NOROUTE $SEEDS
     evaluate tanks "sac_mlp_tanks" $R/runs/tanks -- $FULL
     [ "${OLD:-1}" = 1 ] && evaluate old_sac_mlp_generalist "sac_mlp_generalist" $R/old_runs/sac_mlp_gen_s10 -- $TANKS ;;
  1) train lstm_tanks "td3_lstm_tanks" --config td3_lstm_tanks $SEEDS
     evaluate lstm_tanks "td3_lstm_tanks" $R/runs/lstm_tanks -- $FULL
     [ "${OLD:-1}" = 1 ] && evaluate old_td3_lstm_generalist "td3_lstm_generalist" $R/old_runs/gen_s13 -- $TANKS ;;
  2) train uniform "sac_mlp_tanks, uniform levels" --config sac_mlp_tanks --set levels.sampler=uniform $NOROUTE $SEEDS
     evaluate uniform "sac_mlp_tanks, uniform levels" $R/runs/uniform -- $TANKS ;;
  3) train all_structured "sac_mlp_tanks, every level structured" --config sac_mlp_tanks \
       --set env.layout_structures=1.0 $NOROUTE $SEEDS
     evaluate all_structured "sac_mlp_tanks, every level structured" $R/runs/all_structured -- $TANKS ;;
  4) train route "sac_mlp_tanks, route reward 2" --config sac_mlp_tanks --set levels.route_reward=2.0 $SEEDS
     evaluate route "sac_mlp_tanks, route reward 2" $R/runs/route -- $TANKS ;;
  5) train route_only "sac_mlp_tanks, route reward 2, no progress term" --config sac_mlp_tanks \
       --set levels.route_reward=2.0 --set env.progress_reward_scale=0.0 $SEEDS
     evaluate route_only "sac_mlp_tanks, route reward 2, no progress term" $R/runs/route_only -- $TANKS ;;
  6) train sac_lstm128 "sac_mlp_tanks, LSTM(128) actor" --config sac_mlp_tanks $LSTM128 $NOROUTE $SEEDS
     evaluate sac_lstm128 "sac_mlp_tanks, LSTM(128) actor" $R/runs/sac_lstm128 -- $TANKS ;;
  7) train td3_lstm128 "td3_lstm_tanks, LSTM(128) actor" --config td3_lstm_tanks $LSTM128 $SEEDS
     evaluate td3_lstm128 "td3_lstm_tanks, LSTM(128) actor" $R/runs/td3_lstm128 -- $TANKS ;;
  esac
}
