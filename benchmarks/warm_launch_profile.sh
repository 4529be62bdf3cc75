#!/usr/bin/env bash
# Where a warm launch of the default command spends its time: one cold launch fills the compile
# cache and the program store, then one warm launch under -X importtime and one under cProfile.
#   bash benchmarks/warm_launch_profile.sh OUT_DIR
set -euo pipefail
OUT=${1:?usage: warm_launch_profile.sh OUT_DIR}
mkdir -p "$OUT"
C=$(mktemp -d); A="--config td3_lstm --set train.total_env_steps=819200 --compile-cache $C --no-progress"
python3 -m docrl_jax.train $A --run-dir "$C/r0" > /dev/null 2>&1
python3 -X importtime -m docrl_jax.train $A --run-dir "$C/r1" > /dev/null 2> "$OUT/importtime.txt"
python3 -m cProfile -o "$OUT/warm.prof" -m docrl_jax.train $A --run-dir "$C/r2" > /dev/null 2>&1
cat "$C"/r*/startup.json
python3 -c "import pstats, sys; pstats.Stats(sys.argv[1]).sort_stats('cumulative').print_stats(60)" "$OUT/warm.prof" \
  > "$OUT/warm_launch_profile.txt"
sort -t'|' -k2 -n "$OUT/importtime.txt" | tail -60 > "$OUT/warm_launch_importtime_top.txt"
