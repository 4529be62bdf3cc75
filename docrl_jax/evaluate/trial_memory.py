"""Will the trials fit this machine's memory? Each command that flies trials (evaluate, render,
robustness) checks its counts here before anything compiles, and refuses in one line what cannot fit,
saying how many would.

    check("--trials", 1_000_000, Need(max_steps=500, held=2, rows=2))
    # UsageError: '--trials 1000000: about 92 GB at 500 steps (trial records, the rollout's working
    #              memory, trials.csv rows); this machine has 24 GB free (available host RAM): at most ~250000 trials'

The evaluator's rollout (`rollout.make_rollout`) flies N trials as one program. Per trial it needs:

  * on the device, its records over max_steps (`record_bytes`: every step's position, action, reward and
    two flags, and with `render` the pose, goal, ranges and distance the renderer draws), the program's
    working memory (`WORK_BYTES` + `WORK_STEP_BYTES` a step) and, where trials start from given states
    (the robustness benchmark, tank trials), those states (`START_BYTES`);
  * on the host, the records again with the metrics made from them (`METRIC_STEP_BYTES` a step), for
    each rollout whose trials a command holds at once (`Need.held`: evaluate holds a scenario's
    directions), each trial's row of trials.csv until it is written (`ROW_BYTES`), and a video's frames.

On a CPU the device is the host: both count against its available RAM. On a GPU the device's free
memory (JAX's `memory_stats`) bounds the first, the host's the rest. Measured on CPU for td3_lstm in
scenario 2 (XLA's `memory_analysis()` of the compiled rollout, over N = 64 and 1024 trials at 50 and
500 steps): output bytes = `record_bytes` exactly, temp 12.6 KB a trial + 8.4 bytes a step; an env
state is 2.7 KB in a paper scenario and 6.1 KB with a tank layout (2.1 KB) beside it; a trials.csv row
peaked at 1.2 KB (tracemalloc). The constants round these up. Checked whole: `evaluate --policy td3_lstm
--scenarios 2` peaked 123 MB higher with --trials 1500 than with 100 (88 KB a trial; `Need` counts 92 KB).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from docrl_jax.arguments import UsageError

WORK_BYTES = 16_000       # a trial's share of the rollout's working memory (measured 12.6 KB)
WORK_STEP_BYTES = 9       # ... and a step's (measured 8.4 bytes)
START_BYTES = 8_400       # a trial's initial state and tank layout, where the rollout starts from states
METRIC_STEP_BYTES = 24    # the host's per-step metrics of a trial (displacements, masks of the steps taken)
ROW_BYTES = 1_300         # a trial's row of trials.csv (measured 1.2 KB)
POSE_FLOATS = 7           # qpos of the free joint: position and quaternion
GOAL_FLOATS = 3


def record_bytes(max_steps: int, action_size: int | None = None, render_ranges: int | None = None) -> int:
    """Bytes of one trial's records (`rollout.make_rollout`): positions (T+1, 3) float32, actions (T, A)
    and rewards (T,) float32, the taken and medium flags (T,) bool; with `render_ranges` (the ranges
    of a step, fan and extra beams), the renderer's (T+1) poses, goals, ranges, medium and distance."""
    if action_size is None:
        from docrl_jax.envs import ACTION_SIZE
        action_size = ACTION_SIZE
    steps = int(max_steps)
    total = 4 * 3 * (steps + 1) + 4 * action_size * steps + 4 * steps + 2 * steps
    if render_ranges is not None:
        total += (steps + 1) * (4 * (POSE_FLOATS + GOAL_FLOATS + render_ranges + 1) + 1)
    return total


@dataclass
class Need:
    """What a command holds per trial of the count it checks: `held` rollouts' records at once on the host,
    `rows` trials.csv rows, `frame_bytes` of video frames; `from_states`: its trials start from given
    states (`START_BYTES`); `render_ranges`: a rendering rollout's ranges a step (`record_bytes`)."""
    max_steps: int
    held: int = 1
    rows: int = 0
    from_states: bool = False
    render_ranges: int | None = None
    frame_bytes: int = 0

    def device(self) -> int:
        """Bytes on the device of one trial in one rollout."""
        records = record_bytes(self.max_steps, render_ranges=self.render_ranges)
        return records + WORK_BYTES + WORK_STEP_BYTES * self.max_steps + (START_BYTES if self.from_states else 0)

    def host(self) -> int:
        """Bytes on the host of one trial: its records and metrics in each rollout held, its rows, its frames."""
        records = record_bytes(self.max_steps, render_ranges=self.render_ranges)
        return self.held * (records + METRIC_STEP_BYTES * self.max_steps) + self.rows * ROW_BYTES + self.frame_bytes


def free_memory() -> tuple[int | None, int | None, str]:
    """(free host bytes, free device bytes or None on a CPU, what the device is). Reads the host's
    MemAvailable; a GPU's free memory from JAX (initialising its backend: nothing is compiled)."""
    from docrl_jax import memory
    host = memory.available_host_bytes()
    import jax
    dev = jax.local_devices()[0]
    if dev.platform == "cpu":
        return host, None, "available host RAM"
    device, what = memory.available_device_bytes(dev)
    return host, device, what


def _gb(n: float) -> str:
    return f"{n / 1e9:.0f} GB" if n >= 10e9 else f"{n / 1e9:.1f} GB" if n >= 1e8 else f"{n / 1e6:.0f} MB"


def check(flag: str, count: int, need: Need, unit: str = "trials", free=None) -> None:
    """Refuses (UsageError, one line) a `count` of trials whose estimated memory (`need` per trial)
    exceeds what this machine has free, naming the most that fit. `free`: `free_memory()`'s triple
    (read here when None). Unreadable memory is not refused."""
    host, device, what = free if free is not None else free_memory()
    limits = []   # (free bytes, bytes per trial, what)
    if device is None:
        if host is not None:
            limits.append((host, need.device() + need.host(), what))
    else:
        limits.append((device, need.device(), what))
        if host is not None:
            limits.append((host, need.host(), "available host RAM"))
    for free_bytes, per_trial, where in limits:
        if count * per_trial > free_bytes:
            most = max(0, int(free_bytes // per_trial))
            parts = "trial records, the rollout's working memory" + (", trials.csv rows" if need.rows else "") + \
                    (", video frames" if need.frame_bytes else "")
            fit = f"at most ~{_round_down(most)} {unit}" if most else f"not even one of {_gb(per_trial)}"
            raise UsageError(f"{flag} {count}: about {_gb(count * per_trial)} at {need.max_steps} steps ({parts}); "
                             f"this machine has {_gb(free_bytes)} free ({where}): {fit}")


def _round_down(n: int) -> int:
    """n rounded down to two significant digits (an estimate's count, not a promise to the trial)."""
    if n < 100:
        return n
    scale = 10 ** (int(math.log10(n)) - 1)
    return n // scale * scale
