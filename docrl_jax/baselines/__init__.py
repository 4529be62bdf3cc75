"""Classical baselines, written as pure JAX `docrl_jax.policy.Policy` objects."""

from docrl_jax.baselines.bba import BBAParams, make_bba

__all__ = ["BBAParams", "make_bba"]
