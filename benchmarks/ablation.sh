#!/usr/bin/env bash
# Recipe ablations on every local GPU: time to 90 % in both paper directions (paper reward) for a
# list of variants, each `benchmarks/time_to_success.py` over the given seeds.
#
#   bash benchmarks/ablation.sh VARIANTS_FILE BUDGET_S "SEEDS" OUT_DIR [DEADLINE_S]
#
# VARIANTS_FILE: one variant per line, `tag config [seeds=S1,S2] [section.key=value ...]` (# comments
# allowed); `seeds=` overrides SEEDS for that line, so one line per seed spreads seeds over GPUs.
# TTS_EXTRA: more time_to_success.py arguments for every variant (e.g. "--to-end");
# RUN_ROOT: where the run directories go (default /tmp/ablation_runs; pack them with pack_runs.sh).
# Variants are dealt round-robin to the GPUs (CUDA_VISIBLE_DEVICES), each GPU runs its share one
# after another, so variants on different GPUs run side by side and never share a GPU. No variant
# starts after DEADLINE_S seconds (default 1e9). Results: OUT_DIR/time_to_success_<tag>.{json,md,log}.
set -uo pipefail
variants=$1 budget=$2 seeds=$3 out=$4 deadline=${5:-1000000000}
ngpu=$(nvidia-smi -L 2>/dev/null | wc -l); [ "$ngpu" -ge 1 ] || ngpu=1
mkdir -p "$out"
start=$(date +%s)
mapfile -t lines < <(grep -v '^\s*#' "$variants" | grep -v '^\s*$')
for g in $(seq 0 $((ngpu - 1))); do
  (
    for i in "${!lines[@]}"; do
      [ $((i % ngpu)) -eq "$g" ] || continue
      [ $(( $(date +%s) - start )) -lt "$deadline" ] || { echo "gpu $g: deadline, skipping ${lines[$i]}"; continue; }
      read -r tag config rest <<< "${lines[$i]}"
      sets=(); line_seeds=$seeds
      for kv in $rest; do
        case $kv in seeds=*) line_seeds=${kv#seeds=}; line_seeds=${line_seeds//,/ } ;; *) sets+=(--set "$kv") ;; esac
      done
      read -r -a extra <<< "${TTS_EXTRA:-}"
      CUDA_VISIBLE_DEVICES=$g python3 benchmarks/time_to_success.py --config "$config" --seeds $line_seeds \
        --budget-s "$budget" --tag "$tag" --out "$out" --run-root "${RUN_ROOT:-/tmp/ablation_runs}" \
        --compile-cache default "${extra[@]}" "${sets[@]}" > "$out/driver_$tag.txt" 2>&1
      echo "gpu $g: $tag done at $(( $(date +%s) - start )) s"; tail -n 6 "$out/driver_$tag.txt"
    done
  ) &
done
wait
