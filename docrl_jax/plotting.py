"""`python -m docrl_jax.plotting figure3|curves`, the documented command; the code is docrl_jax.evaluate.plotting."""
from docrl_jax import moved
moved.command(__name__, "docrl_jax.evaluate.plotting")
