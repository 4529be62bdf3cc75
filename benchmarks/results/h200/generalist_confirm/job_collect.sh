#!/usr/bin/env bash
# Waits for the lanes of r21.sh to end (up to a deadline), then returns everything packed as one file
# (a call returns at most 8 files).
set -u
deadline=${1:-200}; R=/tmp/r21; t0=$(date +%s)
alldone() { for g in 0 1 2 3; do [ -e $R/lane_done_$g ] || return 1; done; }
while [ $(( $(date +%s) - t0 )) -lt $deadline ] && ! alldone; do sleep 3; done
cat $R/times; cp $R/times $R/pack/
for f in $R/eval/gen_b2048_s13/robustness.md; do grep -E "^\| (Paper|Random|Held)" $f | head -12; done
tar cf $OUT/r21_all.tar -C $R pack
alldone && echo ALL_DONE
