"""`python -m docrl_jax.evaluate`: the evaluation command (docrl_jax.evaluate.cli)."""
import sys

from docrl_jax.evaluate.cli import main

sys.exit(main())
