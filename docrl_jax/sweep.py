"""`python -m docrl_jax.sweep`: the command of docrl_jax.train.sweep_cli, kept at its short name."""

from docrl_jax.moved import command

if __name__ == "__main__":
    # As `python -m docrl_jax.train.sweep_cli` ends: a third Ctrl-C leaves without an abort (console.exit_process).
    from docrl_jax.train.console import exit_process
    from docrl_jax.train.sweep_cli import main
    exit_process(main())
command(__name__, "docrl_jax.train.sweep_cli", home="docrl_jax.train.sweep")
