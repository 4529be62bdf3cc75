"""What the flyability check costs: `docrl_jax.envs.flyability.check` on one generated layout and vmapped
over a batch of them, compiled first, then the median of a few calls on this machine's first device.

    python benchmarks/flyability_cost.py [--batch 64] [--repeats 5]
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

from docrl_jax.envs import flyability, layouts
from docrl_jax.envs.params import make_params


def main(batch: int = 64, repeats: int = 5) -> None:
    """Prints the time of `check` on one generated layout and vmapped over `batch` of them (compiled)."""
    p = make_params(0)
    many = jax.vmap(lambda i: layouts.generate(layouts.layout_key(i), p))(jnp.arange(batch))
    one = jax.tree.map(lambda x: x[0], many)
    for name, fn, arg in (("one layout", jax.jit(lambda l: flyability.check(l, p)), one),
                          (f"{batch} layouts (vmap)", jax.jit(jax.vmap(lambda l: flyability.check(l, p))), many)):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(arg))
        compiled = time.perf_counter() - t0
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            route = jax.block_until_ready(fn(arg))
            times.append(time.perf_counter() - t0)
        print(f"{name}: compile+first {compiled:.2f} s, then median {np.median(times) * 1e3:.1f} ms "
              f"(min {min(times) * 1e3:.1f}) on {jax.devices()[0].device_kind}; "
              f"flyable A-W {np.mean(np.asarray(route.flyable)[..., 0]):.2f}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    main(args.batch, args.repeats)
