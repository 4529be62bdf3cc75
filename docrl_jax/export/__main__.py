"""`python -m docrl_jax.export`: the export command (docrl_jax.export.cli)."""
from docrl_jax.export.cli import main
from docrl_jax.console import run_main

run_main(main)
