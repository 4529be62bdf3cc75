"""`python -m docrl_jax.train`: the command line (docrl_jax/cli.py) around the trainer program."""

from docrl_jax.cli import main

raise SystemExit(main())
