"""benchmarks/first_crossing.py: the first evaluation at the target both ways, and the chunk at which an
evaluation schedule's target row lands, on hand-made curves worked out by hand."""

import os
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "benchmarks"))
import first_crossing as fc  # noqa: E402


def _curve(from_chunk: int, chunks: int = 20, only_aw: bool = False) -> dict:
    """Both directions at 1.0 from `from_chunk` on (A-W only with only_aw), 0 before."""
    return {c: (1.0 if c >= from_chunk else 0.0, 0.0 if only_aw or c < from_chunk else 1.0) for c in range(chunks)}


def test_the_first_crossing_needs_both_directions(tmp_path):
    assert fc.first_at(_curve(8), 0.9) == 8
    assert fc.first_at(_curve(8, only_aw=True), 0.9) == fc.NEVER
    path = tmp_path / "metrics.csv"
    rows = ["env_steps,seed,success_air_to_water,success_water_to_air"]
    rows += [f"{c * 409600},{seed},{aw},{wa}" for seed, first in ((1, 3), (2, 5)) for c in range(8)
             for aw, wa in [(0.95, 0.9) if c >= first else (0.95, 0.89)]]
    path.write_text("\n".join(rows) + "\n")
    got = fc.curves(str(path))
    assert [fc.first_at(got[s], 0.9) for s in ("1", "2")] == [3, 5]


def test_one_group_every_three_chunks_waits_for_time_outs():
    # Evaluations begin at 0 and 5 (each not at the target keeps the lanes 5 chunks) and 10, which reads a
    # policy at the target from chunk 8 and lands 3 chunks later.
    assert fc.replay(_curve(8), 0.9, groups=1, every=3) == 13
    # A policy at the target from chunk 5 is read by the evaluation begun at 5.
    assert fc.replay(_curve(5), 0.9, groups=1, every=3) == 8


def test_more_groups_begin_evaluations_while_others_run():
    # Five groups, one evaluation every chunk: the evaluation begun at chunk 8 reads it.
    assert fc.replay(_curve(8), 0.9, groups=5, every=1) == 11
    # Two groups, every two chunks: 0 (group a), 2 (b), 5 (a, free again), 7 (b), 10 (a) reads it.
    assert fc.replay(_curve(8), 0.9, groups=2, every=2) == 13
    assert fc.replay(_curve(7), 0.9, groups=2, every=2) == 10
    # Never at the target within the curve: never read.
    assert fc.replay(_curve(30), 0.9, groups=5, every=1) == fc.NEVER
