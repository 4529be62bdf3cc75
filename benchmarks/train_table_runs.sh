#!/usr/bin/env bash
# Trains the four learned rows of the paper's Table I (DoCRL-D = td3_lstm, DoCRL-S = sac_lstm,
# Sto. = sac_mlp, Det. = ddpg_mlp) with identical settings and an identical wall-clock budget, several
# seeds each (vmapped in one process), and packs each run's policy-only checkpoint for CPU evaluation.
#
#     OUT=/tmp/table bash benchmarks/train_table_runs.sh [BUDGET_S] [NUM_SEEDS]
#
# With 4+ GPUs the four configs run at once, one GPU each; otherwise one after another on GPU 0.
# Every run gets `timeout -s INT BUDGET_S` (default 470 s, start-up and compilation included): Ctrl-C
# makes the trainer write its final checkpoint, so each run ends at the env step its budget reached.
# Writes into $OUT: <config>.log (nvidia-smi, versions, the trainer's output) and <config>.tar.gz
# (config.yaml, metrics.csv, the last checkpoint's policy and meta), then a one-line summary each.
# The settings are those of benchmarks/time_to_success.py's H100 runs (docs/BENCHMARKS.md).
set -u
BUDGET_S=${1:-470}
NUM_SEEDS=${2:-3}
OUT=${OUT:?set OUT to the output folder}
RUNS=${RUNS:-/tmp/table_runs}
read -r -a CONFIGS <<<"${TABLE_CONFIGS:-td3_lstm sac_lstm sac_mlp ddpg_mlp}"
SETTINGS=(--set env.num_envs=4096 --set env.progress_reward_scale=10.0 --set agent.tau=0.005
          --set replay.buffer_size=524288 --set train.total_env_steps=250000000
          --set train.num_seeds="$NUM_SEEDS" --set train.log_every=409600 --set train.eval_every=2048000
          --set train.eval_episodes=100 --set train.checkpoint_every=200000000)
read -r -a EXTRA <<<"${TABLE_EXTRA:-}"  # extra --set pairs, e.g. for a CPU smoke test
SETTINGS+=("${EXTRA[@]}")
NUM_GPUS=$(nvidia-smi -L 2>/dev/null | wc -l)
mkdir -p "$OUT" "$RUNS"

train_one() {  # $1 = config, $2 = GPU index
    local log="$OUT/$1.log"
    {
        date -u +"date: %Y-%m-%dT%H:%M:%SZ"
        nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader -i "$2" || echo "no GPU"
        python3 -c "import jax, mujoco, flax, optax, orbax.checkpoint as o; print('jax', jax.__version__, 'mujoco', mujoco.__version__, 'flax', flax.__version__, 'optax', optax.__version__, 'orbax', o.__version__)"
        echo "command: python3 -m docrl_jax.train --config $1 --run-dir $RUNS/$1 --no-progress ${SETTINGS[*]}  (timeout -s INT $BUDGET_S)"
    } >"$log" 2>&1
    CUDA_VISIBLE_DEVICES=$2 timeout -s INT "$BUDGET_S" python3 -m docrl_jax.train --config "$1" \
        --run-dir "$RUNS/$1" --no-progress "${SETTINGS[@]}" >>"$log" 2>&1
    echo "exit code: $?" >>"$log"
}

pack_one() {  # policy-only: the evaluator needs config.yaml and the last checkpoint's policy + meta
    local dir="$RUNS/$1" step
    step=$(ls "$dir/checkpoints" 2>/dev/null | grep -E '^[0-9]+$' | sort -n | tail -1)
    if [ -z "$step" ]; then echo "$1: no checkpoint" >>"$OUT/$1.log"; return; fi
    tar -czf "$OUT/$1.tar.gz" -C "$(dirname "$dir")" "$1/config.yaml" "$1/metrics.csv" \
        "$1/checkpoints/$step/policy" "$1/checkpoints/$step/meta" "$1/checkpoints/$step/_CHECKPOINT_METADATA"
}

if [ "$NUM_GPUS" -ge "${#CONFIGS[@]}" ]; then
    for i in "${!CONFIGS[@]}"; do train_one "${CONFIGS[$i]}" "$i" & done
    wait
else
    for c in "${CONFIGS[@]}"; do train_one "$c" 0; done
fi
for c in "${CONFIGS[@]}"; do
    pack_one "$c"
    printf '%-9s %s | %s\n' "$c" "$(grep -E '^(done|interrupted|exit code)' "$OUT/$c.log" | tr '\n' ' ')" \
        "$(tail -n 1 "$RUNS/$c/metrics.csv" 2>/dev/null)"
done
