"""The DoCRL trainer: one home for everything that trains.

    train = make_train(config)                       # pure: train(key) -> (runner_state, metrics)
    jax.jit(jax.vmap(train))(keys)                   # N seeds in one program

    python -m docrl_jax.train --config td3_lstm [--set section.key=value ...] [--run-dir DIR] [--resume]

Modules, in the order a run uses them:
    trainer      make_train / make_trainer: the scanned program (env steps, replay, updates) of one seed
    evaluation   the deterministic evaluation between chunks (learning curves, paper pairs)
    programs     init / chunk / evaluate jitted over seeds and devices, compiled once
    program_store  the compile cache and the compiled programs kept between launches (prefetched early)
    loop         the one chunk loop (cadences, Ctrl-C, ETA), shared by runs and sweeps
    metrics      metrics.csv rows, TensorBoard scalars, the progress line
    best_policy  each seed's best evaluated policy, kept beside the final one
    cli          `python -m docrl_jax.train`: the command line (light: it starts the programs' prefetch)
    run          one run into its run directory: checkpoints, resume
    sweep        `python -m docrl_jax.sweep`: a hyperparameter grid x seeds with as few programs as it allows
"""

from docrl_jax.moved import lazy_members

# Imported on first use: `python -m docrl_jax.train` imports this package first, and its command line
# starts loading the stored programs before MJX, Flax and Orbax are imported.
__getattr__ = lazy_members(__name__, {
    "load_policy": "docrl_jax.runs",  # kept here too: the evaluator's entry point since the start
    **{name: "docrl_jax.train.trainer" for name in ("RunnerState", "Trainer", "make_train", "make_trainer")}})

__all__ = ["RunnerState", "Trainer", "load_policy", "make_train", "make_trainer"]
