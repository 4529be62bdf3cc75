"""benchmarks/update_cost.py --trace: the kernel table is read from the device's stream lines of a
Perfetto trace, not from the host or from the derived per-op lines that overlap the kernels."""

import gzip
import json
import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
import update_cost  # noqa: E402


def _trace(tmp_path):
    meta = [{"ph": "M", "name": "process_name", "pid": 1, "args": {"name": "/host:CPU"}},
            {"ph": "M", "name": "process_name", "pid": 2, "args": {"name": "/device:GPU:0"}},
            {"ph": "M", "name": "thread_name", "pid": 2, "tid": 14, "args": {"name": "Stream #14(Compute)"}},
            {"ph": "M", "name": "thread_name", "pid": 2, "tid": 76, "args": {"name": "Stream #76(Compute)"}},
            {"ph": "M", "name": "thread_name", "pid": 2, "tid": 9, "args": {"name": "XLA Ops"}}]
    kernels = [("gemm_fusion_dot_1", 14, 10.0)] * 4 + [("loop_add_fusion", 14, 2.0)] * 6 + [("reduce", 76, 5.0)] * 2
    events = meta + [{"ph": "X", "pid": 2, "tid": t, "name": n, "ts": i * 20.0, "dur": d}
                     for i, (n, t, d) in enumerate(kernels)]
    events += [{"ph": "X", "pid": 2, "tid": 9, "name": "fusion.1", "ts": 0.0, "dur": 500.0},      # derived line
               {"ph": "X", "pid": 1, "tid": 3, "name": "PjitFunction", "ts": 0.0, "dur": 900.0}]  # host
    where = tmp_path / "plugins" / "profile" / "run"
    where.mkdir(parents=True)
    with gzip.open(where / "perfetto_trace.json.gz", "wt") as f:
        json.dump({"traceEvents": events}, f)
    return str(tmp_path)


def test_kernels_come_from_the_device_streams_only(tmp_path):
    kernels, lines = update_cost.device_kernels(_trace(tmp_path))
    assert len(kernels) == 12
    assert lines["/device:GPU:0 / XLA Ops"] == [1, 500.0]
    s = update_cost.kernel_summary(kernels, updates=2, wall_ms=0.05)
    assert s["kernels_per_update"] == 6.0
    assert s["busy_ms_per_update"] == (40 + 12 + 10) / 1e3 / 2
    assert s["top"][0] == {"kernel": "gemm_fusion_dot_1", "calls_per_update": 2.0, "us_per_update": 20.0,
                           "share_of_busy": round(40 / 62, 3)}
    kinds = {k["kernel"]: (k["calls_per_update"], k["us_per_update"], k["us_per_call"]) for k in s["kinds"]}
    assert kinds == {"matmul": (2.0, 20.0, 10.0), "elementwise": (3.0, 6.0, 2.0), "reduction": (1.0, 5.0, 5.0)}
    assert sum(r["calls_per_update"] for r in s["all"]) == s["kernels_per_update"]
