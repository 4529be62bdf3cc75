"""The one chunk loop, shared by a training run (docrl_jax.train.run) and a sweep
(docrl_jax.train.sweep): run the compiled chunk, check its metrics, evaluate and checkpoint when
due, show progress, and stop cleanly on Ctrl-C.

What differs between a run and a sweep (what a non-finite loss means, where evaluations are
written, whether there are checkpoints) comes in as `Hooks`; when to evaluate and save is a
`Cadence` each, by env steps or by wall-clock minutes, whichever comes first, so a slow device
still writes learning curves and checkpoints. How an evaluation runs is `Evaluations`': paused
(the evaluation program between chunks) or alongside training (train.eval_alongside: it begins with
the next chunk and its rows are written when its last episode has ended); the final one, and one
running alongside at a checkpoint or a stop, are paused ones.

Ctrl-C (or SIGTERM, as a cluster's scheduler sends before it kills a job) is answered at once:
the loop finishes the running chunk (XLA cannot stop it half-way), saves a checkpoint and stops.
A second one says again what is happening, with the running chunk's time left; a third quits
without waiting (docrl_jax.console.exit_process), keeping the checkpoints already written; none interrupts a
checkpoint being written.
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from concurrent import futures
from dataclasses import dataclass
from typing import Any, Callable

import jax
import numpy as np

from docrl_jax.train import metrics
from docrl_jax.train.chunks import Schedule
from docrl_jax.console import EXIT_INTERRUPTED, EXIT_NONFINITE, EXIT_OK, passing_ctrl_c, waiters
from docrl_jax.train.evaluation import eval_keys
from docrl_jax.train.metrics import duration


class Cadence:
    """When a periodic action is due: each time the env steps cross a multiple of `every_steps`, or
    once `every_minutes` of wall-clock have passed since it was last done (`done`)."""

    def __init__(self, every_steps: int, every_minutes: float, clock: Callable[[], float] = time.monotonic):
        self.every_steps, self.every_s, self.clock = every_steps, every_minutes * 60.0, clock
        self.last = clock()

    def due(self, prev_steps: int, steps: int) -> bool:
        return (steps // self.every_steps > prev_steps // self.every_steps
                or self.clock() - self.last >= self.every_s)

    def done(self) -> None:
        self.last = self.clock()

    def remaining(self, steps: int, total: int) -> int:
        """Env-step occasions left until `total` (the one at the end included)."""
        return total // self.every_steps - steps // self.every_steps + (total % self.every_steps != 0)


class Eta:
    """Time left, from the chunks that learned on every iteration and the evaluations so far. The
    chunks before `train.start_steps` only step the envs and run far faster than the rest of the run,
    so there is no estimate until a learning chunk has been timed."""

    def __init__(self):
        self.chunk_s: list[float] = []
        self.eval_s: list[float] = []
        self.learning = False   # the last chunk learned on every iteration

    def add_eval(self, seconds: float) -> None:
        self.eval_s.append(seconds)

    def add_chunk(self, seconds: float, learning: bool) -> None:
        self.learning = learning
        if learning:
            self.chunk_s.append(seconds)

    def chunk(self) -> float | None:
        """Seconds a learning chunk takes now (the first may include warm-up), or None before one."""
        return float(np.median(self.chunk_s[-10:])) if self.chunk_s else None

    def next_chunk(self) -> float | None:
        """Seconds the chunk after the last one will take: a learning chunk's once the last one
        learned on every iteration; None before (a chunk that only steps the envs is far faster than
        the next may be)."""
        return self.chunk() if self.learning else None

    def seconds(self, chunks_left: int, evals_left: int) -> float | None:
        chunk = self.chunk()
        if chunk is None:
            return None
        per_eval = float(np.median(self.eval_s)) if self.eval_s else 0.0
        return chunks_left * chunk + evals_left * per_eval

    def text(self, chunks_left: int, evals_left: int) -> str:
        s = self.seconds(chunks_left, evals_left)
        return "ETA once learning starts" if s is None else f"ETA {duration(s)}"


class Interrupt:
    """Catches SIGINT and SIGTERM for the loop: `requested` after the first; messages are printed by
    `poll` (called while the loop waits for a chunk) rather than in the handler, so they never
    interleave with the progress display's own writes. They say how long the running chunk has
    left (`chunk_started`), from the time a chunk takes, when that is known."""

    def __init__(self, console, action: str = "saving a checkpoint", clock: Callable[[], float] = time.monotonic):
        self.console, self.action, self.clock = console, action, clock
        self.count, self.said = 0, 0
        self.started, self.expected_s = clock(), None
        self.newest = "none yet"     # what a quit without saving keeps (set by the caller)
        self._saving = self._deferred = False
        self._old: dict = {}

    def __enter__(self):
        self._passing = passing_ctrl_c()     # a command's Ctrl-C watcher hands the presses to `_handle`
        self._passing.__enter__()
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self._old[sig] = signal.signal(sig, self._handle)
            except ValueError:  # not the main thread: signals stay with the caller
                pass
        return self

    def __exit__(self, *exc):
        for sig, old in self._old.items():
            signal.signal(sig, old)
        self._passing.__exit__(None, None, None)

    @property
    def requested(self) -> bool:
        return self.count > 0

    def _handle(self, signum, frame):
        self.count += 1
        if self.count >= 3:
            if self._saving:
                self._deferred = True
            else:
                raise KeyboardInterrupt

    def chunk_started(self, expected_s: float | None) -> None:
        """A chunk began now; it takes about `expected_s` seconds (None: not known yet)."""
        self.started, self.expected_s = self.clock(), expected_s

    @property
    def next_stop(self) -> str:
        """When the loop stops: after the running chunk, and how long that has left."""
        ran = self.clock() - self.started
        if self.expected_s is None:
            return f"after the running chunk (it has run {duration(ran)}; no estimate before a learning chunk is timed)"
        left = self.expected_s - ran
        if left >= 0.5:
            return f"after the running chunk (about {duration(left)} more)"
        return f"after the running chunk (any moment: it has run {duration(ran)}, chunks take about " \
               f"{duration(self.expected_s)})"

    def poll(self) -> None:
        while self.said < self.count:
            self.said += 1
            if self.said == 1:
                self.console.print(f"[bold yellow]stopping[/] {self.next_stop}, then {self.action} "
                                   f"(Ctrl-C twice more quits without it)")
            elif self.said == 2:
                self.console.print(f"[bold yellow]still stopping[/] {self.next_stop}, then {self.action}; one more "
                                   f"Ctrl-C quits without it (newest checkpoint kept: {self.newest})")

    @contextlib.contextmanager
    def saving(self):
        """A checkpoint write is never cut off: a third Ctrl-C during it takes effect once it ends."""
        self._saving = True
        try:
            yield
        finally:
            self._saving = False
            if self._deferred:
                self._deferred = False
                raise KeyboardInterrupt


def wait(tree: Any, interrupt: Interrupt | None = None, poll_s: float = 0.1) -> Any:
    """Blocks until the device has computed `tree`. A helper thread does the blocking, so this
    (main) thread keeps running signal handlers and prints a Ctrl-C's message at once; it wakes the
    moment the result is ready (no polling latency added to a chunk)."""
    ready = threading.Event()
    waiter = threading.Thread(target=lambda: (_block_quietly(tree), ready.set()), daemon=True,
                              name="docrl_jax device wait")
    waiters[:] = [t for t in waiters if t.is_alive()] + [waiter]
    waiter.start()
    while not ready.wait(poll_s):
        if interrupt is not None:
            interrupt.poll()
    if interrupt is not None:
        interrupt.poll()
    return jax.block_until_ready(tree)  # returns at once, or raises the computation's error here


def wait_for_build(program: Any, interrupt: Interrupt, poll_s: float = 0.1) -> None:
    """Returns once `program` can run: at once, or when the first build of a program still compiling (a
    `docrl_jax.train.programs.Tiered`, whose `first` is its future) is done, answering a Ctrl-C meanwhile."""
    first = getattr(program, "first", None)
    while first is not None and not first.done():
        interrupt.poll()
        futures.wait([first], timeout=poll_s)
    interrupt.poll()


def _block_quietly(tree: Any) -> None:
    try:
        jax.block_until_ready(tree)
    except Exception:  # re-raised in the main thread by `wait`
        pass


@dataclass
class Hooks:
    """What a run and a sweep do differently in the loop."""
    check: Callable[[dict, int], bool]            # (chunk metrics on the host, env steps before it) -> go on?
    # When an evaluation's results are in: (env steps, the training statistics since the previous
    # evaluation and the gradient updates made, both as of its env steps, its results, the trained
    # actor's results or {}, a function giving the evaluated policy on the host) -> writes its rows.
    record: Callable[[int, dict, Any, dict, dict, Callable[[], Any]], None]
    show: Callable[[dict, int, float, str], None]  # (chunk metrics, env steps, env steps/s, ETA text)
    save: Callable[[Any, int, int], None] | None = None  # (runner state, env steps, chunks done); None: never


class Evaluations:
    """Runs the evaluations of a run or a sweep (docrl_jax.train.evaluation) for the loop.

    `now`: the evaluation program on the policy as it is, training waits (with `trained_actor`, the
    trained actor too, on the same episodes). When the run's `programs` (docrl_jax.train.programs)
    have evaluation lanes (train.eval_alongside), `begin` asks the next chunk to start the episodes in
    them instead, `collect` records them after the chunk in which the last one ended, and `finish`
    completes one still running with the program, on the same policy and episodes (before a
    checkpoint, at a stop and at the end). `placement` is the run's `sharding.SeedPlacement`, `seeds`
    its seed rows. `pending` holds the chunks' training statistics since the last evaluation began
    (docrl_jax.train.metrics; a checkpoint keeps it)."""

    def __init__(self, programs, placement, seeds: list[int], hooks: Hooks, trained_actor: bool = False,
                 pending: dict | None = None):
        self.evaluate, self.starts = programs.evaluate, programs.eval_starts
        self.placement, self.seeds, self.hooks = placement, seeds, hooks
        self.alongside, self.trained_actor = programs.eval_starts is not None, trained_actor
        self.pending = metrics.empty_pending(len(seeds)) if pending is None else pending
        self.running: tuple | None = None   # (env steps, statistics, updates) of the one running alongside

    def _capture(self, state, steps: int) -> tuple:
        """What the rows of the evaluation at `steps` take from the run at that point."""
        taken, self.pending = self.pending, metrics.empty_pending(len(self.seeds))
        return steps, taken, self.placement.get(state.agent.updates)

    def _keys(self, steps: int):
        return self.placement.put_seeds(np.asarray(eval_keys(self.seeds, steps)))

    def now(self, state, steps: int) -> None:
        captured = self._capture(state, steps)
        keys, get = self._keys(steps), self.placement.get
        results = get(self.evaluate(state.agent.actor_average, keys))
        trained = get(self.evaluate(state.agent.actor, keys)) if self.trained_actor else {}
        self.hooks.record(*captured, results, trained, lambda: get(state.agent.actor_average))

    def begin(self, state, steps: int):
        """(state asking the next chunk to begin the evaluation of `steps`, True), or (state, False)
        while another is still running."""
        if self.running is not None:
            return state, False
        self.running = self._capture(state, steps)
        lanes = state.evals.replace(begin=self.placement.put_seeds(np.ones(len(self.seeds), bool)),
                                    fresh=self.starts(self._keys(steps)))
        return state.replace(evals=lanes), True

    def collect(self, state, m: dict) -> None:
        """Records the evaluation running alongside if its last episode ended in the chunk of `m`."""
        if self.running is None or np.any(np.asarray(m["evaluation"]["running"]) > 0):
            return
        captured, self.running = self.running, None
        results = {k: v for k, v in m["evaluation"].items() if k != "running"}
        self.hooks.record(*captured, results, {}, lambda: self.placement.get(state.evals.params))

    def finish(self, state) -> None:
        """Completes the evaluation running alongside, if any, with the program (training waits)."""
        if self.running is None:
            return
        captured, self.running = self.running, None
        get = self.placement.get
        results = get(self.evaluate(state.evals.params, self._keys(captured[0])))
        self.hooks.record(*captured, results, {}, lambda: get(state.evals.params))

    def first(self, state):
        """The evaluation at step 0 of a fresh run: returns the state to train on."""
        if self.alongside:
            return self.begin(state, 0)[0]
        self.now(state, 0)
        return state


def run_chunks(plan: Schedule, chunk: Callable, state, done_chunks: int, hooks: Hooks, evaluations: Evaluations,
               evals: Cadence, saves: Cadence | None, interrupt: Interrupt, get: Callable = jax.device_get,
               any_process: Callable[[bool], bool] = bool, hp: tuple = (), num_seeds: int = 1,
               stop_after_chunks: int | None = None):
    """Runs chunks from `done_chunks` to the end of the run. Evaluates (`evaluations`) when `evals` is
    due and at the end; saves (when `hooks.save`) when `saves` is due, at the end and when stopped.
    `get` brings the chunk's metrics to the host and `any_process` tells whether any process was
    interrupted (`SeedPlacement.get` and `.any_process`: several processes stop together).
    `stop_after_chunks` acts like a Ctrl-C after that many chunks of this call (tests). Returns
    (state, done_chunks, status)."""
    eta = Eta()
    total = plan.num_chunks * plan.steps_per_chunk
    env_steps = done_chunks * plan.steps_per_chunk
    status, this_call = EXIT_OK, 0
    due = False   # an evaluation is due; alongside, it waits until the running one has ended

    def paused(action, *args):
        """An evaluation training waits for: its time counts towards the ETA."""
        t0 = time.time()
        action(*args)
        eta.add_eval(time.time() - t0)

    interrupt.chunk_started(None)
    wait_for_build(chunk, interrupt)   # a cold start's chunk may still compile
    while done_chunks < plan.num_chunks:
        t0 = time.time()
        interrupt.chunk_started(eta.next_chunk())
        state, m = chunk(state, *hp)
        m = get(wait(m, interrupt))
        dt = time.time() - t0
        if not hooks.check(m, env_steps):
            status = EXIT_NONFINITE
            break
        metrics.accumulate(evaluations.pending, m)
        done_chunks, this_call = done_chunks + 1, this_call + 1
        prev, env_steps = env_steps, done_chunks * plan.steps_per_chunk
        eta.add_chunk(dt, learning=int(np.min(m["learn_iters"])) >= plan.iters_per_chunk)
        final = done_chunks == plan.num_chunks
        evaluations.collect(state, m)
        # Every decision below is agreed over the processes (`any_process`): the evaluation and the
        # save are collective, and each process's wall clock would decide the minutes cadences alone.
        due = due or final or any_process(evals.due(prev, env_steps))
        interrupt.poll()
        stop = any_process(interrupt.requested) or (stop_after_chunks is not None and this_call >= stop_after_chunks)
        save = hooks.save is not None and (final or stop or any_process(saves.due(prev, env_steps)))
        pause = final or stop or not evaluations.alongside
        if final or stop or save:   # an evaluation running alongside is recorded before the checkpoint
            paused(evaluations.finish, state)
        if due and pause:
            paused(evaluations.now, state, env_steps)
            due = False
            evals.done()
        if save:
            with interrupt.saving():
                hooks.save(state, env_steps, done_chunks)
            saves.done()
            interrupt.newest = f"env step {env_steps:,}"
        if due and not pause:       # after the save: a checkpoint holds no evaluation about to begin
            state, began = evaluations.begin(state, env_steps)
            if began:
                due = False
                evals.done()
        sps = plan.steps_per_chunk * num_seeds / dt  # env steps/s of all seeds in this chunk
        # Alongside, only the final evaluation pauses training.
        evals_left = 1 if evaluations.alongside else evals.remaining(env_steps, total)
        hooks.show(m, env_steps, sps, eta.text(plan.num_chunks - done_chunks, evals_left))
        if stop and not final:
            status = EXIT_INTERRUPTED
            break
    return state, done_chunks, status
