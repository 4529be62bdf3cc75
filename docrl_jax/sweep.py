"""`python -m docrl_jax.sweep`: the command of docrl_jax.train.sweep, kept at its short name."""

from docrl_jax.moved import command

command(__name__, "docrl_jax.train.sweep")
