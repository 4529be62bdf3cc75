"""`python -m docrl_jax.robustness`: the command of docrl_jax.evaluate.robustness_cli, kept at its short name."""

from docrl_jax.moved import command

command(__name__, "docrl_jax.evaluate.robustness_cli")
