"""`python -m docrl_jax.train`: the command line (docrl_jax.train.cli) around the trainer program."""

from docrl_jax.train.cli import main
from docrl_jax.console import run_main

run_main(main)
