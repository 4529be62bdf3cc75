"""`python -m docrl_jax.export`: the export command (docrl_jax.export.cli)."""
import sys

from docrl_jax.export.cli import main

sys.exit(main())
