"""Where a cold compile's time goes: runs a command (a training launch with its compilation cache off)
with XLA's own timers switched on (VLOG 1 of the pass pipeline and of the GPU compiler's files) and
sums them per program, per pass and per compiler phase.

    python3 benchmarks/compile_profile.py --out OUT -- python3 -m docrl_jax.train --config td3_lstm \
        --set train.total_env_steps=409600 --no-progress --run-dir /tmp/profile_run

Writes OUT/compile_profile.md (the tables, with the command, GPU and versions) and OUT/xla_vlog.log.gz
(every timer line). XLA's timers overlap: a phase's time holds its passes' times, and the programs
compile in parallel threads, so the sums are CPU time per thread, not wall-clock.
"""

from __future__ import annotations

import argparse
import collections
import gzip
import os
import re
import subprocess
import sys
import time


from docrl_jax.benchmarking import run_meta

# The files whose VLOG(1) timers say where a GPU compile goes.
VMODULE = ("hlo_pass_pipeline=1,gpu_compiler=1,nvptx_compiler=1,compile_module_to_llvm_ir=1,"
           "ptx_compiler_helper=1,subprocess_compilation=1,autotuner_pass=1,gemm_fusion_autotuner=1")
_UNITS = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0, "h": 3600.0}
_LINE = re.compile(r"^[IWE]\d{4} [\d:.]+\s+(\d+) ([\w.]+):\d+\] (.*)$")
_TIME = re.compile(r"^(.*?) time: ([\d.]+) (ns|us|ms|s|min|h)\b")
_PIPELINE = re.compile(r"Running HLO pass pipeline on module ([\w.\-]+): ([\w.\-]+)")


def parse(lines):
    """(the timer lines, per (program, pass): seconds summed over its runs, other timers by label)."""
    module_of = {}                                   # thread -> the program its pipeline runs on
    kept, per_pass, timers = [], collections.Counter(), collections.Counter()
    for line in lines:
        m = _LINE.match(line)
        if not m:
            continue
        thread, _, text = m.groups()
        if p := _PIPELINE.search(text):
            module_of[thread] = p.group(1)
            kept.append(line)
            continue
        t = _TIME.match(text)
        if not t:
            continue
        kept.append(line)
        label, secs = t.group(1).strip(), float(t.group(2)) * _UNITS[t.group(3)]
        if label.startswith("HLO pass: "):
            per_pass[(module_of.get(thread, "?"), label[len("HLO pass: "):])] += secs
        else:
            timers[label] += secs
    return kept, per_pass, timers


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--top", type=int, default=30, help="rows of the pass and timer tables")
    ap.add_argument("command", nargs=argparse.REMAINDER, help="-- then the command to profile")
    args = ap.parse_args(argv)
    command = args.command[1:] if args.command[:1] == ["--"] else args.command
    if not command:
        ap.error("give the command after --")
    os.makedirs(args.out, exist_ok=True)
    env = dict(os.environ, TF_CPP_MIN_LOG_LEVEL="0", TF_CPP_VMODULE=VMODULE, DOCRL_JAX_COMPILE_CACHE="off")
    t0 = time.time()
    proc = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    wall = time.time() - t0
    lines = proc.stdout.splitlines()
    kept, per_pass, timers = parse(lines)
    with gzip.open(os.path.join(args.out, "xla_vlog.log.gz"), "wt") as f:
        f.write("\n".join(kept) + "\n")
    per_module = collections.Counter()
    for (module, _), secs in per_pass.items():
        per_module[module] += secs
    meta = run_meta()
    out = [f"# Where a cold compile goes, by XLA's timers ({meta['gpu']}, {meta['date']})", "",
           f"Profiler: `{meta['command']}`  ", f"Versions: {meta['versions']}", "",
           f"Command: `{' '.join(command)}` (exit {proc.returncode}, {wall:.1f} s wall-clock; "
           "DOCRL_JAX_COMPILE_CACHE=off)", "",
           "Last lines of its output:", "", *("    " + ln for ln in
                                               [x for x in lines if not _LINE.match(x)][-6:]), "",
           "## HLO passes per program (s, summed over the pass pipelines)", "",
           "| program | s |", "|---|---|",
           *(f"| {m} | {s:.2f} |" for m, s in per_module.most_common() if s >= 0.05), "",
           f"## The {args.top} longest passes (s, summed over the pass's runs in its program)", "",
           "| program | pass | s |", "|---|---|---|",
           *(f"| {m} | {p} | {s:.2f} |" for (m, p), s in per_pass.most_common(args.top)), "",
           f"## The {args.top} longest other timers (compiler phases, code generation, autotuning)", "",
           "| timer | s |", "|---|---|",
           *(f"| {label[:160]} | {s:.2f} |" for label, s in timers.most_common(args.top))]
    with open(os.path.join(args.out, "compile_profile.md"), "w") as f:
        f.write("\n".join(out) + "\n")
    print("\n".join(out[-(args.top + 4):]))
    return proc.returncode


if __name__ == "__main__":
    sys.exit(main())
