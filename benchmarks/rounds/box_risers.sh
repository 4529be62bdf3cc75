# Box risers (issue 47, tried): scenario 2's risers drawn per episode as capsules (as scenario 2) or
# as square posts (two orientations), through the tank files in benchmarks/rounds/s2_shapes: does
# meeting box edges in training keep the default's pace and steady it in scenario 3?
#   WHEELS=.whl_min FIRST=4911 COUNT=3 bash benchmarks/gpu_lanes.sh benchmarks/rounds/box_risers.sh 555
# Seeds FIRST.. (default 4911, those of benchmarks/results/h200/every_seed_more, whose raw.tar.gz holds
# the default's runs), one launch at a time, each flown by the evaluator (scenarios 1-3, its final
# policy); then the robustness benchmark's random trips in scenario 3 for both sides.
LANES=${LANES:-"0"}
export DOCRL_JAX_COMPILE_CACHE=$R/cache
lane() {
  local first=${FIRST:-4911}
  for ((seed = first; seed < first + ${COUNT:-3}; seed++)); do
    train b$seed "box risers seed $seed" --config td3_lstm --set train.seed=$seed --set env.scenario=0 \
      --set env.tank=benchmarks/rounds/s2_shapes
    evaluator b${seed}_final "box risers seed $seed" $R/runs/b$seed -- --which final --trials 100 --scenarios 1,2,3
  done
  local new=() old=() raw=$PWD/benchmarks/results/h200/every_seed_more/raw.tar.gz
  mkdir -p $R/old_runs && (cd $R/old_runs && tar xzf $raw && for f in pack/runs_s*.tgz; do tar xzf $f; done)
  for ((seed = first; seed < first + ${COUNT:-3}; seed++)); do
    new+=($R/runs/b$seed); old+=($R/old_runs/s$seed)
  done
  echo "trips3 eval start $(date +%s)" >> $R/times
  python3 -m docrl_jax.robustness --run "${new[@]}" --run "${old[@]}" --label "box risers" --label default \
    --which final --tests random_trips --scenarios 3 --trials 300 --out $R/eval/trips3 > $R/eval_trips3.log 2>&1
  echo "trips3 eval rc=$? $(date +%s)" >> $R/times
  (cd $R && tar czf pack/eval_trips3.tgz eval/trips3 eval_trips3.log)
}
