#!/usr/bin/env bash
# On this repository's CPU, after cpu_eval.sh: the blind hull contacts of the config now (prog2 seeds
# 10-12), classified as in ../generalist_slant_beams (every beam, slanted included, above 0.5 m).
set -u
while ! grep -q perturbations_rc30 eval_rc_cpu 2>/dev/null; do sleep 10; done
python ../generalist_slant_beams/blind_geometry.py 1000 final runs/gen_slant8e30_prog2_s10:0 \
  runs/gen_slant8e30_prog2_s10:1 runs/gen_slant8e30_prog2_s10:2 > blind_geometry_prog2.log 2>&1
python ../generalist_slant_beams/blind_geometry_summary.py blind_geometry_prog2.log > blind_geometry_prog2_summary.txt 2>&1
