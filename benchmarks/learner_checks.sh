#!/usr/bin/env bash
# The learner measurements of docs/BENCHMARKS.md ("Why the defaults are what they are"), one job per GPU, side by side:
#   GPU 0: trainer throughput at 4,096 envs: the code before the learner rework (checked out into
#          .old/, `git archive d036a67 docrl_jax configs assets benchmarks | tar -x -C .old`) with
#          its td3_lstm recipe, then this code with td3_lstm_paper (today's recipe), td3_lstm (the new
#          default) and td3_lstm at batch 4,096; then sac_lstm's default, seed 0, to its end.
#   GPUs 1-3: td3_lstm's default with train.total_env_steps=$TD3_STEPS, seeds 0, 1, 2, to their end.
#   bash benchmarks/learner_checks.sh OUT_DIR [TD3_STEPS]
set -u
out=$1 steps=${2:-100000000}
mkdir -p "$out"
(
  export CUDA_VISIBLE_DEVICES=0
  [ -d .old ] && PYTHONPATH=/tmp/site:$PWD/.old python3 .old/benchmarks/train_throughput.py --configs td3_lstm \
      --num-envs 4096 --iters 40 --repeats 3 --out "$out/throughput_old_code" > "$out/throughput_old_code.txt" 2>&1
  python3 benchmarks/train_throughput.py --configs td3_lstm_paper td3_lstm --num-envs 4096 --iters 40 --repeats 3 \
      --out "$out" > "$out/throughput_new_code.txt" 2>&1
  python3 benchmarks/train_throughput.py --configs td3_lstm --num-envs 4096 --iters 40 --repeats 3 \
      --set replay.batch_size=4096 --stem train_throughput_b4096 --out "$out" > "$out/throughput_b4096.txt" 2>&1
  python3 benchmarks/time_to_success.py --config sac_lstm --seeds 0 --to-end --budget-s 280 --compile-cache default \
      --tag sac_lstm_default --run-root /tmp/runs --out "$out" > "$out/driver_sac.txt" 2>&1
) &
for s in 0 1 2; do
  CUDA_VISIBLE_DEVICES=$((s + 1)) python3 benchmarks/time_to_success.py --config td3_lstm --seeds $s --to-end \
      --budget-s 330 --compile-cache default --tag "td3_lstm_${steps}_seed$s" --run-root /tmp/runs --out "$out" \
      --set train.total_env_steps=$steps > "$out/driver_td3_$s.txt" 2>&1 &
done
wait
tail -n 4 "$out"/throughput_*.txt; grep -h "seed" "$out"/driver_*.txt
