"""Stable-Baselines3 TD3 gradient steps per second, for `mentalsim bench learner`.

Same shapes as ours: a Box observation of --obs-dim values, a 2-D Box action, actor and critics
with --hidden layers, --batch-size transitions per step, a buffer of random transitions. Times
`model.train(gradient_steps=N)`, which samples from the buffer and updates critics, actor (every
policy_delay steps) and targets: the same work as our `Learner::update`. Prints one JSON line.
"""

import argparse
import json
import time

import gymnasium as gym
import numpy as np
import torch
import stable_baselines3
from stable_baselines3 import TD3


class Dummy(gym.Env):
    def __init__(self, obs_dim):
        self.observation_space = gym.spaces.Box(-1.0, 1.0, (obs_dim,), np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)

    def reset(self, seed=None, options=None):
        return np.zeros(self.observation_space.shape, np.float32), {}

    def step(self, action):
        return np.zeros(self.observation_space.shape, np.float32), 0.0, False, False, {}


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--obs-dim", type=int, default=25)
    p.add_argument("--hidden", default="256,256")
    p.add_argument("--batch-size", type=int, default=256)
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--warmup", type=int, default=100)
    p.add_argument("--buffer", type=int, default=100000)
    p.add_argument("--threads", type=int, default=1)
    a = p.parse_args()
    if a.threads > 0:
        torch.set_num_threads(a.threads)
    hidden = [int(h) for h in a.hidden.split(",")]
    model = TD3(
        "MlpPolicy",
        Dummy(a.obs_dim),
        learning_rate=3e-4,
        buffer_size=a.buffer,
        batch_size=a.batch_size,
        gamma=0.99,
        tau=0.005,
        policy_delay=2,
        target_policy_noise=0.2,
        target_noise_clip=0.5,
        policy_kwargs=dict(net_arch=hidden),
        device="cpu",
        seed=1,
    )
    rng = np.random.default_rng(1)
    rb = model.replay_buffer
    n = a.buffer
    rb.observations[:n, 0] = rng.random((n, a.obs_dim), dtype=np.float32)
    rb.next_observations[:n, 0] = rng.random((n, a.obs_dim), dtype=np.float32)
    rb.actions[:n, 0] = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
    rb.rewards[:n, 0] = rng.random(n, dtype=np.float32) - 0.5
    rb.dones[:n, 0] = (rng.random(n) < 0.02).astype(np.float32)
    rb.pos = 0
    rb.full = True
    model._logger = stable_baselines3.common.logger.configure(None, [""])
    model.train(gradient_steps=a.warmup, batch_size=a.batch_size)
    t = time.perf_counter()
    model.train(gradient_steps=a.steps, batch_size=a.batch_size)
    dt = time.perf_counter() - t
    print(json.dumps({
        "grad_steps_per_s": a.steps / dt,
        "version": stable_baselines3.__version__,
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
    }))


if __name__ == "__main__":
    main()
