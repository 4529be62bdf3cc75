#!/usr/bin/env bash
# The default td3_lstm command of two versions of the code, launch by launch, interleaved per seed
# (A seed s, B seed s, A seed s+1, ...), each stopped at 90 % success both ways by
# benchmarks/time_to_success.py; each version keeps its own persistent compile cache, so the first
# launch of each is cold and the rest warm.
#
# Here (with git):   rm -rf .old && mkdir .old && git archive REV docrl_jax configs assets \
#                        benchmarks/time_to_success.py benchmarks/common.py | tar -x -C .old
#                    echo /.old/ >> .git/info/exclude
# GPU machine:       bash benchmarks/ab_launches.sh "0 1" 150      (carry .old; $OUT gets one .tgz)
# Then:              python3 benchmarks/ab_summary.py DIR ...      (the table of the launches)
set -u
NEW=$PWD; OLD=$PWD/.old; SEEDS=${1:-"0 1"}; BUDGET=${2:-150}; WORK=/tmp/ab
mkdir -p $WORK
for s in $SEEDS; do
  for side in old new; do
    R=$NEW; [ $side = old ] && R=$OLD
    (cd $R && DOCRL_JAX_COMPILE_CACHE=/tmp/cache_$side PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}$R python3 \
       benchmarks/time_to_success.py --config td3_lstm --seeds $s --compile-cache default --budget-s $BUDGET \
       --out $WORK/$side --tag ${side}_s$s --run-root $WORK/runs_$side) 2>&1 | grep "seed $s:"
  done
done
(cd $WORK && find . -path '*checkpoints*' -prune -o -path '*/tb' -prune -o -type f -print |
   tar -czf ${OUT:-/tmp}/ab_$(echo $SEEDS | tr ' ' '_').tgz -T -)
