"""`python -m docrl_jax`: the `docrl` command line (docrl_jax.commands)."""

from docrl_jax.commands import entry

entry()
