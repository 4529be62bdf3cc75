"""`python -m docrl_jax.evaluate`: the evaluation command (docrl_jax.evaluate.cli)."""
from docrl_jax.evaluate.cli import main
from docrl_jax.console import run_main

run_main(main)
