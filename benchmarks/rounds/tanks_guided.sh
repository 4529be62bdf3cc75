# Tanks a person builds, trained with route guidance (docs/LEVELS.md, "Route guidance"): sac_mlp_tanks_guided
# (levels.guide) on seeds 0-2, one launch per GPU of a 4-GPU host, and on the fourth GPU the same with uniform
# level sampling (seed 0: a hint, not a measurement); each final policy then flies the gallery (350 trips each
# way) and the 1,000 held-out structured tanks guided and, the same trials, unguided (benchmarks/route_follower.py).
#   bash benchmarks/gpu_lanes.sh benchmarks/rounds/tanks_guided.sh
LANES="0 1 2 3"
SETS="--trials 350 --layouts 1000"
fly() { name=$1; shift; mode=guided; [ "${1:-}" = --unguided ] && mode=mapless
  echo "$name fly $mode start $(date +%s)" >> $R/times
  python3 benchmarks/route_follower.py $SETS --policy $R/runs/$name:0 "$@" --out $R/eval/$name/$mode > $R/fly_${name}_$mode.log 2>&1
  echo "$name fly $mode rc=$? $(date +%s)" >> $R/times
  (cd $R && tar czf pack/fly_${name}_$mode.tgz eval/$name/$mode fly_${name}_$mode.log); }
lane() {
  case $1 in
  3) train guided_uniform "sac_mlp_tanks_guided, uniform levels" --config sac_mlp_tanks_guided \
       --set levels.sampler=uniform --set train.seed=0
     fly guided_uniform; fly guided_uniform --unguided ;;
  *) train guided_s$1 "sac_mlp_tanks_guided seed $1" --config sac_mlp_tanks_guided --set train.seed=$1
     fly guided_s$1; fly guided_s$1 --unguided ;;
  esac
}
