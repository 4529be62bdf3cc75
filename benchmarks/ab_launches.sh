#!/usr/bin/env bash
# The default td3_lstm command of two (or more) versions of the code, or of overrides of one version,
# launch by launch, interleaved per seed (A seed s, B seed s, A seed s+1, ...), each stopped at 90 %
# success both ways by benchmarks/time_to_success.py; each side keeps its own persistent compile
# cache, so the first launch of each is cold and the rest warm.
#
# Here (with git):   rm -rf .old && mkdir .old && git archive REV docrl_jax configs assets \
#                        benchmarks/time_to_success.py benchmarks/common.py | tar -x -C .old
#                    echo /.old/ >> .git/info/exclude
# GPU machine:       bash benchmarks/ab_launches.sh "0 1" 150      (carry .old; $OUT gets one .tgz)
# Then:              python3 benchmarks/ab_summary.py DIR ...      (the table of the launches)
#
# Two overrides of one tree: OLD_TREE=$PWD NEW_ARGS="--set env.vel_i_rate=0.3" bash ... ; OLD_ARGS and
# NEW_ARGS are extra time_to_success.py arguments for one side, BOTH_ARGS for every side (--to-end: every
# launch runs to its end, and its final policy is packed beside the logs by benchmarks/pack_runs.sh).
# More sides: SIDES="old new fast" with TREE_fast (default this tree), ARGS_fast and CACHE_fast (a
# compile-cache folder, default its own; name another side's to share it).
set -u
NEW=$PWD; SEEDS=${1:-"0 1"}; BUDGET=${2:-150}; WORK=${WORK:-/tmp/ab}; SIDES=${SIDES:-"old new"}
TREE_old=${TREE_old:-${OLD_TREE:-$PWD/.old}}; ARGS_old=${ARGS_old:-${OLD_ARGS:-}}; ARGS_new=${ARGS_new:-${NEW_ARGS:-}}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p $WORK
for s in $SEEDS; do
  for side in $SIDES; do
    eval "R=\${TREE_$side:-$NEW} ARGS=\${ARGS_$side:-} CACHE=\${CACHE_$side:-/tmp/cache_$side}"
    (cd $R && DOCRL_JAX_COMPILE_CACHE=$CACHE PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$R python3 \
       benchmarks/time_to_success.py --config td3_lstm --seeds $s --compile-cache default --budget-s $BUDGET \
       --out $WORK/$side --tag ${side}_s$s --run-root $WORK/runs_$side ${BOTH_ARGS:-} $ARGS) 2>&1 | grep "seed $s:"
  done
done
TAG=$(echo $SEEDS | tr ' ' '_')
(cd $WORK && find . -path '*checkpoints*' -prune -o -path '*/tb' -prune -o -type f -print |
   tar -czf ${OUT:-/tmp}/ab_$TAG.tgz -T -)
case " ${BOTH_ARGS:-} " in *" --to-end "*)
  for side in $SIDES; do bash $HERE/pack_runs.sh $WORK/runs_$side ${OUT:-/tmp}/policies_${side}_$TAG.tgz; done;;
esac
