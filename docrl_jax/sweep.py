"""`python -m docrl_jax.sweep`: the command of docrl_jax.train.sweep_cli, kept at its short name."""

from docrl_jax.moved import command

if __name__ == "__main__":
    from docrl_jax.console import run_main
    from docrl_jax.train.sweep_cli import main
    run_main(main)   # as `python -m docrl_jax.train.sweep_cli` runs
command(__name__, "docrl_jax.train.sweep_cli", home="docrl_jax.train.sweep")
