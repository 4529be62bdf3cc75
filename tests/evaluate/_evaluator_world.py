"""The env of the evaluator's tests (tests/evaluate/test_evaluate.py, test_video.py): the same sizes give
the same compiled rollout, so the second file reuses the first's program."""

MAX_STEPS = 200
LOW_FLOOR = (-3.0, 4.8)  # z bounds below the floor (top -1.3), so a dive ends on the floor
N = 6
