#!/usr/bin/env bash
# Trains the four learned rows of the paper's Table I (DoCRL-D = td3_lstm, DoCRL-S = sac_lstm,
# Sto. = sac_mlp, Det. = ddpg_mlp), several seeds each (vmapped in one process), and packs each run's
# policy-only checkpoint for CPU evaluation.
#
#     OUT=/tmp/table bash benchmarks/train_table_runs.sh [BUDGET_S] [NUM_SEEDS]
#
# TABLE_RECIPE chooses the settings:
#   defaults          (default) the packaged configs as they are, each run to its own end
#                     (train.total_env_steps); BUDGET_S defaults to 0 = no time limit.
#   table_2026_11_21  the first Table I (docs/RESULTS.md lineage): the *_paper configs with 4,096 envs,
#                     tau 0.005, a 524,288-step buffer, the dense progress term, stopped BUDGET_S
#                     (default 470) after launch; add TABLE_EXTRA="--set env.progress_reward_scale=0.0"
#                     for the paper's reward.
# Configs are queued round-robin over the GPUs (config i on GPU i mod #GPUs; each GPU runs its queue
# in order), so 4 GPUs run all four at once and 2 GPUs two at a time. A BUDGET_S > 0 gives every run
# `timeout -s INT BUDGET_S` (start-up and compilation included): Ctrl-C makes the trainer write its
# final checkpoint, so the run ends at the env step its budget reached.
# Writes into $OUT: <config>.log (nvidia-smi, versions, the command, the trainer's output) and
# <config>.tar.gz (config.yaml, metrics.csv, the last checkpoint's policy and meta), then a one-line
# summary each.
set -u
RECIPE=${TABLE_RECIPE:-defaults}
NUM_SEEDS=${2:-3}
OUT=${OUT:?set OUT to the output folder}
RUNS=${RUNS:-/tmp/table_runs}
case "$RECIPE" in
    defaults)
        BUDGET_S=${1:-0}
        DEFAULT_CONFIGS="td3_lstm sac_lstm sac_mlp ddpg_mlp"
        SETTINGS=(--set train.num_seeds="$NUM_SEEDS") ;;
    table_2026_11_21)
        BUDGET_S=${1:-470}
        DEFAULT_CONFIGS="td3_lstm_paper sac_lstm_paper sac_mlp_paper ddpg_mlp_paper"
        SETTINGS=(--set env.num_envs=4096 --set env.progress_reward_scale=10.0 --set agent.tau=0.005
                  --set replay.buffer_size=524288 --set train.total_env_steps=250000000
                  --set train.num_seeds="$NUM_SEEDS" --set train.log_every=409600 --set train.eval_every=2048000
                  --set train.eval_episodes=100 --set train.checkpoint_every=200000000) ;;
    *) echo "unknown TABLE_RECIPE '$RECIPE'; valid: defaults, table_2026_11_21" >&2; exit 2 ;;
esac
read -r -a CONFIGS <<<"${TABLE_CONFIGS:-$DEFAULT_CONFIGS}"
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
        echo "command: python3 -m docrl_jax.train --config $1 --run-dir $RUNS/$1 --no-progress ${SETTINGS[*]}  (recipe $RECIPE, budget ${BUDGET_S} s, 0 = none)"
    } >"$log" 2>&1
    local limit=()
    [ "$BUDGET_S" -gt 0 ] && limit=(timeout -s INT "$BUDGET_S")
    CUDA_VISIBLE_DEVICES=$2 "${limit[@]}" python3 -m docrl_jax.train --config "$1" \
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

queue() {  # $1 = GPU index: its configs, one after another
    local i
    for i in "${!CONFIGS[@]}"; do
        [ $((i % NUM_GPUS)) -eq "$1" ] && train_one "${CONFIGS[$i]}" "$1"
    done
}
[ "$NUM_GPUS" -ge 1 ] || NUM_GPUS=1   # no GPU: everything in order on the CPU
for g in $(seq 0 $((NUM_GPUS - 1))); do queue "$g" & done
wait
for c in "${CONFIGS[@]}"; do
    pack_one "$c"
    printf '%-9s %s | %s\n' "$c" "$(grep -E '^(done|interrupted|exit code)' "$OUT/$c.log" | tr '\n' ' ')" \
        "$(tail -n 1 "$RUNS/$c/metrics.csv" 2>/dev/null)"
done
