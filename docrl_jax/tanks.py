"""`python -m docrl_jax.tanks` (`docrl tanks`): the command of docrl_jax.envs.tanks_cli, kept at its short name."""

from docrl_jax.moved import command

command(__name__, "docrl_jax.envs.tanks_cli")
