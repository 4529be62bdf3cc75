# Launch to end of one packaged recipe (issue 47: <= 3 minutes warm for the generalists), as a user runs it:
# the README's command with only its seed and run directory set, LAUNCHES launches one after the other on
# one GPU (lane 0), sharing one compilation cache that is empty at the start, so the first launch compiles
# and the later ones load. `times` holds each launch's wall clock, each run's startup.json its start-up.
#   WHEELS=.whl_gpu CONFIG=sac_mlp_tanks bash benchmarks/gpu_lanes.sh benchmarks/rounds/recipe_end.sh [DEADLINE_S]
LANES=0
export DOCRL_JAX_COMPILE_CACHE=$R/cache
lane() {
  for ((i = 0; i < ${LAUNCHES:-2}; i++)); do
    train ${CONFIG}_s$i "$CONFIG seed $i" --config $CONFIG --set train.seed=$i
  done
}
