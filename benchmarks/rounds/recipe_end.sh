# Launch to end of packaged recipes (the target: <= 3 minutes warm for the generalists), as a user runs them:
# the README's command with only its seed and run directory set, LAUNCHES launches one after the other on
# one GPU, sharing one compilation cache that is empty at the start, so the first launch compiles and the
# later ones load. CONFIG is one recipe, or several separated by spaces: lane N runs the N-th on GPU N.
# `times` holds each launch's wall clock, each run's startup.json its start-up.
#   WHEELS=.whl_gpu CONFIG=sac_mlp_tanks bash benchmarks/gpu_lanes.sh benchmarks/rounds/recipe_end.sh [DEADLINE_S]
#   WHEELS=.whl_gpu CONFIG="sac_mlp_generalist sac_mlp_tanks" LAUNCHES=4 bash benchmarks/gpu_lanes.sh ...
read -ra RECIPES <<< "$CONFIG"
LANES=$(seq -s ' ' 0 $(( ${#RECIPES[@]} - 1 )))
export DOCRL_JAX_COMPILE_CACHE=$R/cache
lane() {
  local recipe=${RECIPES[$1]}
  for ((i = 0; i < ${LAUNCHES:-2}; i++)); do
    train ${recipe}_s$i "$recipe seed $i" --config $recipe --set train.seed=$i
  done
}
