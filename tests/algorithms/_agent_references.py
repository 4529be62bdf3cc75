"""Hand computations the agents' tests compare against (NumPy, from the parameters): shared by the tests
of tests/algorithms/."""

import math

import jax
import numpy as np


def mlp(p, x, layers):
    """A ReLU MLP of Flax Dense layers `layers` (names in `p`), the last one linear."""
    for name in layers[:-1]:
        x = np.maximum(x @ p[name]["kernel"] + p[name]["bias"], 0.0)
    return x @ p[layers[-1]]["kernel"] + p[layers[-1]]["bias"]


def q(p, obs, act, i):
    """Head i of the vmapped critic ensemble (parameters stacked on axis 0)."""
    head = jax.tree.map(lambda x: x[i], p["params"]["q"])
    return mlp(head, np.concatenate([obs, act], -1), ["dense_0", "out"])[..., 0]


def gauss_head(p, x):
    """(mean, clipped log std) of the one-hidden-layer Gaussian actor."""
    pp = p["params"]
    h = np.maximum(x @ pp["dense_0"]["kernel"] + pp["dense_0"]["bias"], 0.0)
    mean = h @ pp["head"]["mean"]["kernel"] + pp["head"]["mean"]["bias"]
    log_std = np.clip(h @ pp["head"]["log_std"]["kernel"] + pp["head"]["log_std"]["bias"], -20.0, 2.0)
    return mean, log_std


def tanh_gauss(mean, log_std, eps):
    """The tanh-squashed sample at noise `eps` and its log-probability."""
    u = mean + np.exp(log_std) * eps
    a = np.tanh(u)
    logp = np.sum(-0.5 * eps ** 2 - log_std - 0.5 * math.log(2 * math.pi) - np.log(1 - a ** 2 + 1e-6), -1)
    return a, logp
