"""`python -m docrl_jax.sweep`: the command of docrl_jax.train.sweep, kept at its short name."""

from docrl_jax.moved import command

if __name__ == "__main__":
    # As `python -m docrl_jax.train.sweep` ends: a third Ctrl-C leaves without an abort (loop.exit_process).
    from docrl_jax.train.loop import exit_process
    from docrl_jax.train.sweep import main
    exit_process(main())
command(__name__, "docrl_jax.train.sweep")
