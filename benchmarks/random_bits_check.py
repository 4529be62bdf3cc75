"""Whether JAX's threefry kernel lowering (`docrl_jax.train.programs.kernel_random`, on a GPU) draws the same
bits as the default lowering: a normal, a uniform and a randint draw, compiled both ways, compared bit for bit.

    python3 benchmarks/random_bits_check.py        # prints whether the kernel call is in the program, and equality
"""

import jax
import numpy as np

from docrl_jax.train.programs import kernel_random


def draws(key):
    a, b = jax.random.split(key)
    return (jax.random.normal(a, (4096, 20)), jax.random.uniform(b, (4096, 32, 2)),
            jax.random.randint(b, (1024,), 0, 99999))


if __name__ == "__main__":
    key = jax.random.PRNGKey(7)
    plain = jax.jit(draws).lower(key).compile()(key)
    with kernel_random(True):
        lowered = jax.jit(draws).lower(key)
    print("kernel call in HLO:", "threefry2x32_ffi" in lowered.as_text())
    kernel = lowered.compile()(key)
    print("bitwise equal:", all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(plain, kernel)))
