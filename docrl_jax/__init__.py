"""docrl_jax: DoCRL (double-critic deep RL for a hybrid aerial-underwater vehicle) in JAX and MJX."""
__version__ = "0.1.0"
