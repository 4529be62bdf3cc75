#!/usr/bin/env bash
# Packs run directories policy-only for the way back from the GPU machine and for committing:
# config.yaml, metrics.csv, startup.json and the last checkpoint's policy, best policy (where the run
# tracks one) and meta of every run directory under RUN_ROOT (full checkpoints hold the replay
# buffer, hundreds of MB).
#   bash benchmarks/pack_runs.sh RUN_ROOT OUT.tar.gz
set -u
root=$1 out=$2 files=()
for dir in "$root"/*/; do
  name=$(basename "$dir")
  for f in config.yaml metrics.csv startup.json; do [ -f "$dir/$f" ] && files+=("$name/$f"); done
  step=$(ls "$dir/checkpoints" 2>/dev/null | grep -E '^[0-9]+$' | sort -n | tail -1)
  [ -n "$step" ] && files+=("$name/checkpoints/$step/policy" "$name/checkpoints/$step/meta"
                            "$name/checkpoints/$step/_CHECKPOINT_METADATA")
  [ -n "$step" ] && [ -d "$dir/checkpoints/$step/best" ] && files+=("$name/checkpoints/$step/best")
done
tar -czf "$out" -C "$root" "${files[@]}"
