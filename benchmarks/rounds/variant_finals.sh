# A variant of the default against the default's final policies of the same seeds: seeds
# FIRST.. (default 4911, those of benchmarks/results/h200/every_seed_more, whose raw.tar.gz holds the
# default's runs; docs/results-archive.md has the command that puts that folder back first), COUNT of them (default 3), one launch at a time of `td3_lstm` with ARGS (train
# overrides), each flown by the evaluator (scenarios 1-3, its final policy); then the robustness
# benchmark's random trips in scenario 3 (300 per direction) for the variant's and the default's finals.
#   WHEELS=.whl_min ARGS="--set ..." NAME=b LABEL="box risers" FIRST=4911 COUNT=3 \
#     bash benchmarks/gpu_lanes.sh benchmarks/rounds/variant_finals.sh 555
# NAME: the launches' prefix (NAMESEED); LABEL: the variant's name in the tables.
LANES=${LANES:-"0"}
export DOCRL_JAX_COMPILE_CACHE=$R/cache
lane() {
  local first=${FIRST:-4911} prefix=${NAME:-v} tag=${LABEL:-variant}  # not name/label: train sets those
  for ((seed = first; seed < first + ${COUNT:-3}; seed++)); do
    train $prefix$seed "$tag seed $seed" --config td3_lstm --set train.seed=$seed ${ARGS:-}
    evaluator $prefix${seed}_final "$tag seed $seed" $R/runs/$prefix$seed -- --which final --trials 100 --scenarios 1,2,3
  done
  local new=() old=() raw=$PWD/benchmarks/results/h200/every_seed_more/raw.tar.gz
  mkdir -p $R/old_runs && (cd $R/old_runs && tar xzf $raw && for f in pack/runs_s*.tgz; do tar xzf $f; done)
  for ((seed = first; seed < first + ${COUNT:-3}; seed++)); do
    new+=($R/runs/$prefix$seed); old+=($R/old_runs/s$seed)
  done
  echo "trips3 eval start $(date +%s)" >> $R/times
  python3 -m docrl_jax.robustness --run "${new[@]}" --run "${old[@]}" --label "$tag" --label default \
    --which final --tests random_trips --scenarios 3 --trials 300 --out $R/eval/trips3 > $R/eval_trips3.log 2>&1
  echo "trips3 eval rc=$? $(date +%s)" >> $R/times
  (cd $R && tar czf pack/eval_trips3.tgz eval/trips3 eval_trips3.log)
}
