# Tanks a person builds (docs/TANKS.md, "Results"): the new recipes against the generalists on one 2-GPU host,
# two launches per GPU at once, each 3 vmapped seeds, evaluated on its GPU on the gallery, the held-out
# structured tanks, the held-out procedural layouts, random trips in scenarios 1-3 and the paper pairs.
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/tanks.sh
# The generalists' policies are those of their own round (benchmarks/results/h200/generalist_confirm/runs),
# carried to the machine in .jobs/old_runs; OLD=0 leaves their evaluation out.
LANES="0 1 2 3"
TESTS="--tests perturbations,random_trips,held_out_layouts,structured,tanks --perturbations none --trials 350 --layouts 1000"
OLD_TESTS="--tests structured,tanks --trials 350 --layouts 1000"
lane() {
  case $1 in
  0) train tanks_s0 "sac_mlp_tanks" --config sac_mlp_tanks --set train.num_seeds=3 --set train.seed=0
     evaluate tanks_s0 "sac_mlp_tanks" $R/runs/tanks_s0 -- $TESTS
     [ "${OLD:-1}" = 1 ] && evaluate old_sac_mlp_generalist "sac_mlp_generalist" $R/old_runs/sac_mlp_gen_s10 -- $OLD_TESTS ;;
  1) train lstm_tanks_s0 "td3_lstm_tanks" --config td3_lstm_tanks --set train.num_seeds=3 --set train.seed=0
     evaluate lstm_tanks_s0 "td3_lstm_tanks" $R/runs/lstm_tanks_s0 -- $TESTS
     [ "${OLD:-1}" = 1 ] && evaluate old_td3_lstm_generalist "td3_lstm_generalist" $R/old_runs/gen_s13 -- $OLD_TESTS ;;
  2) train tanks_uniform_s0 "sac_mlp_tanks, levels uniform" --config sac_mlp_tanks --set levels.sampler=uniform \
       --set train.num_seeds=3 --set train.seed=0
     evaluate tanks_uniform_s0 "sac_mlp_tanks, levels uniform" $R/runs/tanks_uniform_s0 -- $TESTS ;;
  3) train tanks_route_s0 "sac_mlp_tanks, route reward 2" --config sac_mlp_tanks --set levels.route_reward=2.0 \
       --set train.num_seeds=3 --set train.seed=0
     evaluate tanks_route_s0 "sac_mlp_tanks, route reward 2" $R/runs/tanks_route_s0 -- $TESTS ;;
  esac
}
