"""A docrl_jax actor exported for deployment, run with NumPy alone (no JAX, Flax or docrl_jax).

Standalone on purpose: `python -m docrl_jax.export` copies this file beside the weights, so the two
can be dropped on the vehicle's computer. One step per control period (0.2 s):

    policy = NumpyPolicy("policy_weights.npz")
    carry = policy.initial_carry()                    # zeros: at every episode start
    action, carry = policy.step(observation, carry)   # observation (1, 26) float32 -> action (1, 3)

The math is Flax's: `OptimizedLSTMCell` (gates i, f, g, o; the input kernels `i*` have no bias, the
hidden kernels `h*` carry it; c' = f c + i g, h' = o tanh(c')), or ReLU Dense layers for an MLP actor,
then the deterministic action tanh(Dense(h)) (TD3/DDPG; SAC: its mean head). The carry is (c, h), each
(batch, units); an MLP actor, or an LSTM trained without memory, has none: `()`.
"""

import numpy as np

GATES = ("i", "f", "g", "o")   # Flax's order of the LSTM gates


def _sigmoid(x):
    return 0.5 * np.tanh(0.5 * x) + 0.5   # = 1 / (1 + exp(-x)), without overflow for large |x|


class NumpyPolicy:
    def __init__(self, path):
        with np.load(path, allow_pickle=False) as w:
            self.actor, self.recurrent = str(w["actor"]), bool(w["recurrent"])
            if self.actor == "lstm":   # Flax's names: lstm/i{gate}/kernel, lstm/h{gate}/{kernel,bias}
                self.w_in = np.concatenate([w[f"lstm/i{g}/kernel"] for g in GATES], axis=-1)
                self.w_hid = np.concatenate([w[f"lstm/h{g}/kernel"] for g in GATES], axis=-1)
                self.bias = np.concatenate([w[f"lstm/h{g}/bias"] for g in GATES], axis=-1)
                self.units = self.w_hid.shape[0]
            else:
                self.layers = [(w[f"dense_{k}/kernel"], w[f"dense_{k}/bias"]) for k in range(int(w["num_hidden"]))]
            self.head = (w["head/kernel"], w["head/bias"])

    def initial_carry(self, batch_size=1):
        """The carry at an episode's start: zeros (c, h) for an LSTM with memory, else ()."""
        if not self.recurrent:
            return ()
        zeros = np.zeros((batch_size, self.units), np.float32)
        return (zeros, zeros.copy())

    def step(self, observation, carry=()):
        """observation (batch, 26) -> (action (batch, 3) in [-1, 1], the next carry)."""
        x = np.asarray(observation, np.float32)
        if self.actor == "lstm":
            if self.recurrent:
                c, h = carry
            else:   # trained without memory: a zero carry on every step
                c = h = np.zeros(x.shape[:-1] + (self.units,), np.float32)
            z = (h @ self.w_hid + self.bias) + x @ self.w_in   # Flax adds the hidden part first
            i, f, g, o = np.split(z, 4, axis=-1)
            c = _sigmoid(f) * c + _sigmoid(i) * np.tanh(g)
            h = _sigmoid(o) * np.tanh(c)
            carry = (c, h) if self.recurrent else ()
        else:
            h = x
            for kernel, bias in self.layers:
                h = np.maximum(h @ kernel + bias, 0.0)
        return np.tanh(h @ self.head[0] + self.head[1]), carry
