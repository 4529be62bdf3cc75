"""The `--set` arguments that train any packaged config "the generalist's way": the env section of
`configs/td3_lstm_generalist.yaml` (procedural tanks, random starts, goals and headings, the
domain-randomisation envelope, the controller's integral, the vertical and slanted beams, the training
rewards, the collision and hull margins) and where its paper-pair evaluation runs.
The envelope stays written once, in that config.

    python3 -m docrl_jax.train --config sac_lstm $(python3 benchmarks/generalist_sets.py) --set train.num_seeds=3
"""

from __future__ import annotations

import yaml

from docrl_jax.resources import resource_dir


def generalist_sets() -> list[str]:
    raw = yaml.safe_load((resource_dir("configs") / "td3_lstm_generalist.yaml").read_text())
    sets = [f"env.{k}={v if not isinstance(v, list) else '[' + ','.join(map(str, v)) + ']'}" for k, v in raw["env"].items()]
    return sets + [f"train.eval_pair_scenario={raw['train']['eval_pair_scenario']}"]


if __name__ == "__main__":
    print(" ".join(f"--set {s}" for s in generalist_sets()))
