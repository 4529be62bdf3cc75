"""--guide: a learned policy steered down each trial's route (docrl_jax.baselines.route.guided) in evaluate,
robustness and render. What the guided rollout flies is tested in tests/baselines/test_route_follower.py (the rollout
plans each trial itself) and tests/envs/test_guidance.py (the observation it sees); here, how the commands load and
label it, and the one line that refuses to guide the BBA, which reads its goal from the env."""

import subprocess
import sys

import pytest

from docrl_jax.baselines import route
from docrl_jax.evaluate import policies


def test_a_guided_policy_plans_per_trial_and_says_so():
    policy, label = policies.policy_for(None, name="sac_mlp_generalist", guide="tank")
    plain, plain_label = policies.policy_for(None, name="sac_mlp_generalist")
    assert label == policies.guided_label(plain_label) != plain_label
    assert policy.trial_params is not None and plain.trial_params is None
    assert policy.params["policy"] is not None and policy.params["plan"] is None
    assert policy.trial_axes == route.PLAN_AXES
    # Policies of one act function share one guided act: the guided rollout compiles once for them.
    assert route.guided(plain).act is policy.act


@pytest.mark.parametrize("command", [
    ["docrl_jax.evaluate", "--policy", "bba"],
    ["docrl_jax.robustness", "--policy", "bba"],
    ["docrl_jax.render", "--policy", "bba"],
])
def test_guide_refuses_bba_in_one_line(command):
    out = subprocess.run([sys.executable, "-m", *command, "--guide"], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "--guide" in lines[0] and "bba" in lines[0], out.stderr
