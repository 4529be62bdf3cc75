"""`python -m docrl_jax.render`: the command of docrl_jax.evaluate.video, kept at its short name."""

from docrl_jax.moved import command

command(__name__, "docrl_jax.evaluate.video")
