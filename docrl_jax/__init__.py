"""docrl_jax: DoCRL (double-critic deep RL for a hybrid aerial-underwater vehicle) in JAX and MJX."""

from docrl_jax import moved

moved.install()  # importing a module by its old name says where it lives now

__version__ = "0.1.0"
