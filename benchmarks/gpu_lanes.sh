#!/usr/bin/env bash
# Runs a job of training and evaluation launches on the GPUs of one host, one lane per GPU, and
# brings back what has ended by a deadline, so a device call's time limit never loses a finished run.
#   bash benchmarks/gpu_lanes.sh ROUND [DEADLINE_S]     (on the GPU machine, from the checkout's root)
# JOB is a bash file (benchmarks/rounds/*.sh) that sets LANES (e.g. "0 1 2 3"; lane N runs on GPU N mod
# the host's GPUs, several lanes on one GPU sharing its memory) and defines
# `lane N`, which calls, one after the other:
#   train NAME LABEL TRAIN_ARGS...   python -m docrl_jax.train TRAIN_ARGS into runs/NAME, packed policy-only
#   target NAME LABEL SEED ARGS...   the same launch watched by benchmarks/time_to_success.py (ARGS are its
#     own: --config, --set) and stopped at 90 % success both ways: a time to 90 % without the run's end
#   evaluate NAME LABEL RUN_DIRS... -- ROBUSTNESS_ARGS...   python -m docrl_jax.robustness into eval/NAME
#   evaluator NAME LABEL RUN_DIRS... -- EVALUATE_ARGS...    python -m docrl_jax.evaluate (the paper's protocol)
#     into eval/NAME, without figures; packed without the trajectories (.npz) and with the training log
#     of each run evaluated; its compiled trials are kept in JAX's cache of the job (eval_cache)
# The first call installs the carried wheels (WHEELS, default .whl; with the tracked tree grown past ~30 MB,
# carry .whl_gpu from benchmarks/slim_wheels.py instead: the carry limit is 64 MiB), copies the code aside and starts every lane in its
# own process session; each later call only waits. Call the later ones with --wait first
# (`bash benchmarks/gpu_lanes.sh --wait ROUND [DEADLINE_S]`): where the machine went back between calls and
# this one is fresh, --wait stops at once with one line, where a plain call would start the job again from
# its first seed on device time (start it again with FIRST/COUNT at the first seed not yet packed).
# Every call waits up to DEADLINE_S (default 540),
# prints the lanes' times, the logs' last lines, the robustness tables and the evaluator's successes, and
# copies the packed results (one archive per launch and per evaluation) to $OUT.
set -u
wait_only=0; [ "${1:-}" = "--wait" ] && { wait_only=1; shift; }
round=$1 deadline=${2:-540}
R=/tmp/round_$(basename "$round" .sh)
if [ $wait_only = 1 ] && [ ! -e $R/started ]; then
  echo "gpu_lanes --wait: $(basename "$round" .sh) has not started on this machine (a fresh one: the last went back);" \
       "start it again without --wait, FIRST/COUNT at the first seed not yet packed" >&2
  exit 3
fi
mkdir -p $R/runs $R/eval $R/pack
source "$round"
if [ ! -e $R/started ]; then
  touch $R/started
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site ${WHEELS:-.whl}/*.whl
  rm -rf $R/wt && mkdir $R/wt && cp -r docrl_jax assets configs benchmarks $R/wt/
  [ -d .jobs/old_runs ] && cp -r .jobs/old_runs $R/old_runs
  nvidia-smi --query-gpu=name,driver_version --format=csv > $R/pack/gpu.txt
  PYTHONPATH=/tmp/site python3 -c "import jax, jaxlib, mujoco; print('jax', jax.__version__, 'jaxlib', jaxlib.__version__, 'mujoco', mujoco.__version__)" \
    >> $R/pack/gpu.txt 2>&1
  cat > $R/lane.sh <<LANE
R=$R; cd \$R/wt; export PYTHONPATH=/tmp/site:\$R/wt
# Lane N runs on GPU N mod the GPUs; lanes sharing a GPU split its memory (XLA would take 75 % each).
gpus=\$(nvidia-smi -L | wc -l); export CUDA_VISIBLE_DEVICES=\$(( \$1 % gpus ))
[ \$(echo $LANES | wc -w) -gt \$gpus ] && export XLA_PYTHON_CLIENT_MEM_FRACTION=0.45
pack_run() { mkdir -p \$R/one_\$1 && cp -r \$2 \$R/one_\$1/\$1 && bash benchmarks/pack_runs.sh \$R/one_\$1 \$R/pack/runs_\$1.tgz; }  # NAME RUN_DIR
train() { name=\$1 label=\$2; shift 2
  echo "\$name train start \$(date +%s)" >> \$R/times
  python3 -m docrl_jax.train "\$@" --set name=\$name --no-progress --run-dir \$R/runs/\$name > \$R/\$name.log 2>&1
  echo "\$name train rc=\$? \$(date +%s)" >> \$R/times
  pack_run \$name \$R/runs/\$name; }
target() { name=\$1 label=\$2 seed=\$3; shift 3
  echo "\$name train start \$(date +%s)" >> \$R/times
  python3 benchmarks/time_to_success.py --seeds \$seed --compile-cache default --budget-s 150 --run-root \$R/tts \\
    --tag \$name --out \$R/tts "\$@" > \$R/tts_\$name.log 2>&1
  echo "\$name train rc=\$? \$(date +%s)" >> \$R/times
  cp \$R/tts/time_to_success_\${name}_seed\$seed.log \$R/\$name.log
  pack_run \$name \$R/tts/\${name}_seed\$seed; }
evaluate() { name=\$1 label=\$2; shift 2; runs=()
  while [ "\$1" != "--" ]; do runs+=(--run "\$1"); shift; done; shift
  echo "\$name eval start \$(date +%s)" >> \$R/times
  python3 -m docrl_jax.robustness "\${runs[@]}" --label "\$label" --out \$R/eval/\$name "\$@" > \$R/eval_\$name.log 2>&1
  echo "\$name eval rc=\$? \$(date +%s)" >> \$R/times
  (cd \$R && tar czf pack/eval_\$name.tgz eval/\$name eval_\$name.log \$(ls \$name.log 2>/dev/null)); }
evaluator() { name=\$1 label=\$2; shift 2; runs=()
  while [ "\$1" != "--" ]; do runs+=("\$1"); shift; done; shift
  echo "\$name eval start \$(date +%s)" >> \$R/times
  JAX_COMPILATION_CACHE_DIR=\$R/eval_cache python3 -m docrl_jax.evaluate --run "\${runs[@]}" --label "\$label" \\
    --out \$R/eval/\$name --figures 0 "\$@" > \$R/eval_\$name.log 2>&1
  echo "\$name eval rc=\$? \$(date +%s)" >> \$R/times
  logs=(); for run in "\${runs[@]}"; do [ -e \$R/\$(basename \$run).log ] && logs+=(\$(basename \$run).log); done
  (cd \$R && tar czf pack/eval_\$name.tgz --exclude='*.npz' eval/\$name eval_\$name.log "\${logs[@]}"); }
source $PWD/$round
lane \$1
touch \$R/lane_done_\$1
LANE
  for g in $LANES; do setsid nohup bash $R/lane.sh $g >/dev/null 2>&1 & done
fi
t0=$(date +%s)
alldone() { for g in $LANES; do [ -e $R/lane_done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/pack/gpu.txt $R/times 2>/dev/null
for f in $R/*.log; do echo "== $(basename $f): $(tail -n 2 $f | cut -c1-250)"; done
for f in $R/eval/*/robustness.md; do echo "== $f"; grep -E "^\| " $f | head -30; done
for f in $R/eval/*/results.csv; do [ -e "$f" ] && python3 - "$f" <<'SUCCESS'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
print("==", sys.argv[1].split("/")[-2] + ":", "  ".join(f"s{r['scenario']} {'A-W' if r['direction'] == 'air_to_water' else 'W-A'}"
                                                f" {r['successes']}/{r['trials']}" for r in rows))
SUCCESS
done
cp $R/times $R/pack/ 2>/dev/null
# One archive of the launches' and evaluations' packs ($OUT takes 8 files).
tar cf $OUT/$(basename $R).tar -C $R pack
ls -la $OUT
alldone && echo ALL_DONE
