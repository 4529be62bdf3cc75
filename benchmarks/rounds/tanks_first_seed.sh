# A first reading of the structured-level recipe on one 2-GPU host: sac_mlp_tanks, and the same with the
# route reward, one seed each on its own GPU, half the recipe's env steps (25 M: what the session's device
# time left), evaluated there on the held-out structured tanks and the gallery (docs/LEVELS.md, "Results").
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/tanks_first_seed.sh 300
LANES="0 1"
TESTS="--tests structured,tanks --trials 350 --layouts 1000"
lane() {
  case $1 in
  0) train tanks_seed0 "sac_mlp_tanks" --config sac_mlp_tanks --set train.seed=0 --set train.total_env_steps=25000000
     evaluate tanks_seed0 "sac_mlp_tanks" $R/runs/tanks_seed0 -- $TESTS ;;
  1) train tanks_route_seed0 "sac_mlp_tanks, route reward 2" --config sac_mlp_tanks --set levels.route_reward=2.0 \
       --set train.seed=0 --set train.total_env_steps=25000000
     evaluate tanks_route_seed0 "sac_mlp_tanks, route reward 2" $R/runs/tanks_route_seed0 -- $TESTS ;;
  esac
}
