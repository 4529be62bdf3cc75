"""The controller's velocity integral (`env.vel_i_band`, `env.vel_i_rate`) against steady
disturbances and command steps: what each setting of `vel_i_rate` holds and what it costs.

    python benchmarks/controller_integral.py --rates 0 0.1 0.3 --out benchmarks/results/cpu/controller_integral

Physics only (no policy, no GPU needed), scenario 1 without wind, 80 control steps (16 s) each:
- a hover in air with the plant's mass x1.1 (from 3.5 m) and x0.9 (from 1.0 m): the altitude lost or
  gained, the vertical speed at the end and the integral there (it must reach (s - 1) g / ki to hold
  the weight error);
- command steps on the nominal plant from a 2 m hover: 4 s up at full speed (0.25 m/s), 4 s down,
  4 s forward, 4 s of hover: the peak speeds (the overshoot) and the speed left at the end;
- a hover under water (0.9 m deep) with buoyancy x4 and with a 0.3 m/s current: the largest drift
  from the start and the speed at the end.
"""

from __future__ import annotations

import argparse
import os

import numpy as np


HOVER = (-1.0, 0.0, 0.0)


def measure(rate: float) -> dict:
    import jax
    import jax.numpy as jnp

    import docrl_jax.envs as envs

    def run(position, actions, key=0, **overrides):
        env = envs.make(1, wind=False, vel_i_rate=rate, **overrides)

        def body(s, a):
            s = env.step(s, a)
            return s, (s.info["position"], s.info["velocity"], s.done)
        s0 = jax.jit(env.reset_to)(jax.random.PRNGKey(key), jnp.asarray(position, jnp.float32), 0.0,
                                   jnp.array([0.0, 0.0, 4.5]))
        final, (pos, vel, done) = jax.jit(lambda s, a: jax.lax.scan(body, s, a))(s0, jnp.asarray(actions, jnp.float32))
        return final, np.asarray(pos), np.asarray(vel), bool(np.asarray(done).any())

    hover = np.tile(HOVER, (80, 1))
    row = {"vel_i_rate": rate}
    for scale, z0 in ((1.1, 3.5), (0.9, 1.0)):
        final, pos, vel, done = run((0.0, 0.0, z0), hover, dr_mass_scale=(scale, scale))
        row[f"mass x{scale}"] = {"altitude change m": round(float(pos[-1, 2] - z0), 2),
                                 "largest change m": round(float(np.abs(pos[:, 2] - z0).max()), 2),
                                 "vz at the end m/s": round(float(vel[-1, 2]), 3),
                                 "integral at the end": round(float(final.sim.vel_integral[2]), 3), "ended": done}
    steps = np.concatenate([np.tile((-1.0, 1.0, 0.0), (20, 1)), np.tile((-1.0, -1.0, 0.0), (20, 1)),
                            np.tile((1.0, 0.0, 0.0), (20, 1)), hover[:20]])
    _, _, vel, _ = run((0.0, 0.0, 2.0), steps)
    row["command steps"] = {"up peak m/s (0.25)": round(float(vel[:20, 2].max()), 3),
                            "down peak m/s (-0.25)": round(float(vel[20:40, 2].min()), 3),
                            "forward peak m/s (0.25)": round(float(np.linalg.norm(vel[40:60, :2], axis=1).max()), 3),
                            "speed left after 4 s of hover m/s": round(float(np.linalg.norm(vel[-5:], axis=1).max()), 3)}
    for name, overrides in (("buoyancy x4", {"dr_hull_volume_scale": (4.0, 4.0)}),
                            ("current 0.3 m/s", {"dr_current_speed": (0.3, 0.3)})):
        _, pos, vel, done = run((0.0, 0.0, -0.9), hover, key=1, **overrides)
        row[f"water, {name}"] = {"largest drift m": round(float(np.linalg.norm(pos - pos[0], axis=1).max()), 2),
                                 "speed at the end m/s": round(float(np.linalg.norm(vel[-1])), 3), "ended": done}
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rates", type=float, nargs="+", default=[0.0, 0.1, 0.3])
    p.add_argument("--out", required=True)
    a = p.parse_args()
    from common import run_meta
    import json
    rows = [measure(r) for r in a.rates]
    meta = run_meta()
    os.makedirs(a.out, exist_ok=True)
    with open(os.path.join(a.out, "controller_integral.json"), "w") as f:
        json.dump({**meta, "results": rows}, f, indent=1)
    cases = [k for k in rows[0] if k != "vel_i_rate"]
    lines = [f"# The controller's integral: env.vel_i_rate ({meta['device']}, {meta['date']})", "",
             f"Command: `{meta['command']}`  ", f"Versions: {meta['versions']}", "",
             "| case | measure | " + " | ".join(f"vel_i_rate {r['vel_i_rate']:g}" for r in rows) + " |",
             "|---|---|" + "---|" * len(rows)]
    for case in cases:
        for measure_name in rows[0][case]:
            lines.append(f"| {case} | {measure_name} | " + " | ".join(str(r[case][measure_name]) for r in rows) + " |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "controller_integral.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
