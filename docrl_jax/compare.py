"""`python -m docrl_jax.compare`, the documented command; the code is docrl_jax.evaluate.compare."""
from docrl_jax import moved
moved.command(__name__, "docrl_jax.evaluate.compare")
