# Route guidance in the product: `sac_mlp_tanks` (the shipped seed and its two siblings, final
# policies of benchmarks/results/h100x4/tanks_memory's `runs/route`, not retrained) flown with --guide by
# the commands a user runs, on every test the guided goals name (docs/LEVELS.md): the gallery and the held-out structured
# tanks, the 1,000 held-out procedural layouts, random trips in scenarios 1-3, the goal perturbations
# (scenarios 1-3) and the paper's pairs; lane 3 flies the same seeds unguided on the same trials.
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/guided.sh
# Unpack runs/route of benchmarks/results/h100x4/tanks_memory/raw.tar.gz into .jobs/old_runs/runs first
# (the archive is in git history: docs/results-archive.md has the command that brings it back).
LANES=${LANES:-"0 1 2 3"}   # LANES="0 1 2": the guided lanes only
RUN=$R/old_runs/runs/route
TANKS="--tests structured,tanks --trials 350 --layouts 1000"
PERT="--perturbations wind_gusts,water_current,motor_lag,action_latency,beam_dropout,mass"
REST="--tests perturbations,random_trips,held_out_layouts $PERT --trials 100 --layouts 1000"
PAIRS="--trials 100 --scenarios 1,2,3"
lane() {
  if [ $1 -lt 3 ]; then
    evaluate tanks_g$1 "sac_mlp_tanks guided" $RUN -- --guide --which final --seed-index $1 $TANKS
    evaluate rest_g$1 "sac_mlp_tanks guided" $RUN -- --guide --which final --seed-index $1 $REST
    evaluator pairs_g$1 "sac_mlp_tanks guided" $RUN -- --guide --which final --seed-index $1 $PAIRS
  else
    evaluate rest_u "sac_mlp_tanks" $RUN -- --which final $REST
    evaluator pairs_u "sac_mlp_tanks" $RUN -- --which final $PAIRS
  fi
}
