"""PPO on phalanx's vectorised environment, in NumPy alone: the standard loop (rollouts of
`num_envs` teams stepped in one call, GAE, clipped surrogate, minibatch epochs) with one
small network shared by every agent.

    pip install ./crates/phalanx-py
    python examples/python/ppo_vector.py --iterations 30

Each agent is one sample: its observation (the four channels and the goal vector,
flattened) goes through a one-hidden-layer MLP with a policy head (logits of the five
actions, the disallowed ones masked out) and a value head, trained on its own reward.
The vector's arrays are overwritten by every step, so the rollout copies them into its own
buffers. Auto-reset is in the same step: where an episode was truncated, the value of its
last observation (`infos["final_obs"]`) is added to the reward as the bootstrap, and the
advantage does not run across the episode's end. The gradients are written out by hand (no
deep-learning framework needed); swap in torch for larger networks.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import phalanx

KEYS = ("obstacles", "agents", "cost", "formation")


def features(obs: dict[str, np.ndarray]) -> np.ndarray:
    """`[num_envs, agents, F]`: the four channels flattened and the goal vector."""
    e, n = obs["goal"].shape[:2]
    parts = [obs[k].reshape(e, n, -1) for k in KEYS] + [obs["goal"]]
    return np.concatenate(parts, axis=-1)


class Net:
    """`x -> tanh(x W1 + b1) -> (logits, value)`, with Adam."""

    def __init__(self, n_in: int, hidden: int, n_actions: int, rng: np.random.Generator):
        self.p = {
            "w1": rng.normal(0, np.sqrt(1 / n_in), (n_in, hidden)),
            "b1": np.zeros(hidden),
            "wp": rng.normal(0, 0.01, (hidden, n_actions)),
            "bp": np.zeros(n_actions),
            "wv": rng.normal(0, np.sqrt(1 / hidden), (hidden, 1)),
            "bv": np.zeros(1),
        }
        self.m = {k: np.zeros_like(v) for k, v in self.p.items()}
        self.v = {k: np.zeros_like(v) for k, v in self.p.items()}
        self.t = 0

    def forward(self, x: np.ndarray, mask: np.ndarray):
        h = np.tanh(x @ self.p["w1"] + self.p["b1"])
        logits = h @ self.p["wp"] + self.p["bp"]
        logits = np.where(mask, logits, -1e9)
        logits = logits - logits.max(-1, keepdims=True)
        logp = logits - np.log(np.exp(logits).sum(-1, keepdims=True))
        value = (h @ self.p["wv"] + self.p["bv"])[..., 0]
        return h, logp, value

    def adam(self, grads: dict[str, np.ndarray], lr: float) -> None:
        self.t += 1
        for k, g in grads.items():
            self.m[k] = 0.9 * self.m[k] + 0.1 * g
            self.v[k] = 0.999 * self.v[k] + 0.001 * g * g
            m_hat = self.m[k] / (1 - 0.9**self.t)
            v_hat = self.v[k] / (1 - 0.999**self.t)
            self.p[k] -= lr * m_hat / (np.sqrt(v_hat) + 1e-8)


def ppo_update(net: Net, batch: dict[str, np.ndarray], args) -> dict[str, float]:
    """Epochs of minibatch steps on the clipped surrogate, the value loss and the entropy
    bonus; the gradients by hand."""
    n = len(batch["x"])
    rng = np.random.default_rng(args.seed)
    stats = {"policy_loss": 0.0, "value_loss": 0.0, "entropy": 0.0, "clip_fraction": 0.0}
    count = 0
    for _ in range(args.epochs):
        order = rng.permutation(n)
        for start in range(0, n, args.minibatch):
            i = order[start : start + args.minibatch]
            x, mask, a = batch["x"][i], batch["mask"][i], batch["actions"][i]
            adv, ret, logp_old = batch["adv"][i], batch["ret"][i], batch["logp"][i]
            adv = (adv - adv.mean()) / (adv.std() + 1e-8)
            h, logp, value = net.forward(x, mask)
            m = len(i)
            rows = np.arange(m)
            ratio = np.exp(logp[rows, a] - logp_old)
            clipped = np.clip(ratio, 1 - args.clip, 1 + args.clip)
            # d(-min(r A, clip(r) A))/d logp_a: -r A where the unclipped term is the minimum.
            unclipped = ratio * adv <= clipped * adv
            d_logp_a = np.where(unclipped, -ratio * adv, 0.0) / m
            p = np.exp(logp)
            d_logits = -p * d_logp_a[:, None]
            d_logits[rows, a] += d_logp_a
            # Entropy bonus: d(-c H)/dz_j = c p_j (log p_j + H).
            plogp = np.where(mask, p * logp, 0.0)
            entropy = -plogp.sum(-1)
            d_logits += args.ent_coef * np.where(mask, p * (logp + entropy[:, None]), 0.0) / m
            d_value = args.vf_coef * (value - ret) / m
            grads = {
                "wp": h.T @ d_logits,
                "bp": d_logits.sum(0),
                "wv": h.T @ d_value[:, None],
                "bv": np.array([d_value.sum()]),
            }
            d_h = d_logits @ net.p["wp"].T + d_value[:, None] @ net.p["wv"].T
            d_pre = d_h * (1 - h * h)
            grads["w1"] = x.T @ d_pre
            grads["b1"] = d_pre.sum(0)
            norm = np.sqrt(sum((g * g).sum() for g in grads.values()))
            scale = min(1.0, args.max_grad_norm / (norm + 1e-8))
            net.adam({k: g * scale for k, g in grads.items()}, args.lr)
            stats["policy_loss"] += float(-np.minimum(ratio * adv, clipped * adv).mean())
            stats["value_loss"] += float(0.5 * ((value - ret) ** 2).mean())
            stats["entropy"] += float(entropy.mean())
            stats["clip_fraction"] += float((np.abs(ratio - 1) > args.clip).mean())
            count += 1
    return {k: v / count for k, v in stats.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=30)
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=32, help="rollout steps per iteration")
    parser.add_argument("--size", type=int, default=16)
    parser.add_argument("--agents", type=int, default=3)
    parser.add_argument("--task", default="pathfinding")
    parser.add_argument("--hidden", type=int, default=64)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--gae-lambda", type=float, default=0.95)
    parser.add_argument("--clip", type=float, default=0.2)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--minibatch", type=int, default=1024)
    parser.add_argument("--ent-coef", type=float, default=0.01)
    parser.add_argument("--vf-coef", type=float, default=0.5)
    parser.add_argument("--max-grad-norm", type=float, default=0.5)
    parser.add_argument("--reward-scale", type=float, default=0.01)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    env = phalanx.vector_env(
        args.num_envs, size=args.size, agents=args.agents, task=args.task, seed=args.seed
    )
    rng = np.random.default_rng(args.seed)
    obs, _ = env.reset()
    x = features(obs)
    e, n, f = x.shape
    net = Net(f, args.hidden, 5, rng)
    t_max = args.steps
    buf = {
        "x": np.zeros((t_max, e, n, f), np.float32),
        "mask": np.zeros((t_max, e, n, 5), bool),
        "actions": np.zeros((t_max, e, n), np.int64),
        "logp": np.zeros((t_max, e, n)),
        "value": np.zeros((t_max, e, n)),
        "reward": np.zeros((t_max, e, n)),
        "done": np.zeros((t_max, e, n), bool),
    }
    returns = np.zeros(e)
    finished: list[tuple[float, bool]] = []
    print(f"PPO on phalanx.vector_env: {e} envs x {n} agents, {args.size}² maps, {args.task}")
    for iteration in range(args.iterations):
        started = time.perf_counter()
        for t in range(t_max):
            mask = obs["action_mask"].astype(bool)
            _, logp, value = net.forward(x, mask)
            # Sample from the masked softmax (Gumbel-max).
            actions = np.argmax(logp - np.log(-np.log(rng.random(logp.shape))), axis=-1)
            buf["x"][t], buf["mask"][t], buf["actions"][t] = x, mask, actions
            buf["logp"][t] = np.take_along_axis(logp, actions[..., None], -1)[..., 0]
            buf["value"][t] = value
            obs, rewards, terminations, truncations, infos = env.step(actions)
            reward = rewards * args.reward_scale
            returns += rewards.sum(1)
            ended = infos["_final_obs"]
            truncated = truncations[:, 0] & ended
            if truncated.any():
                # Bootstrap the cut episodes from their last observation.
                final = infos["final_obs"]
                final_mask = final["action_mask"][truncated].astype(bool)
                _, _, final_value = net.forward(features(final)[truncated], final_mask)
                reward[truncated] += args.gamma * final_value
            buf["reward"][t], buf["done"][t] = reward, ended[:, None]
            for i in np.flatnonzero(ended):
                finished.append((returns[i], bool(terminations[i, 0])))
                returns[i] = 0.0
            x = features(obs)
        sampled = time.perf_counter() - started
        _, _, next_value = net.forward(x, obs["action_mask"].astype(bool))
        adv = np.zeros((t_max, e, n))
        last = np.zeros((e, n))
        for t in reversed(range(t_max)):
            following = next_value if t == t_max - 1 else buf["value"][t + 1]
            alive = ~buf["done"][t]
            delta = buf["reward"][t] + args.gamma * following * alive - buf["value"][t]
            last = delta + args.gamma * args.gae_lambda * alive * last
            adv[t] = last
        batch = {
            "x": buf["x"].reshape(-1, f),
            "mask": buf["mask"].reshape(-1, 5),
            "actions": buf["actions"].reshape(-1),
            "logp": buf["logp"].reshape(-1),
            "adv": adv.reshape(-1),
            "ret": (adv + buf["value"]).reshape(-1),
        }
        stats = ppo_update(net, batch, args)
        recent = finished[-200:]
        mean_return = np.mean([r for r, _ in recent]) if recent else float("nan")
        success = np.mean([s for _, s in recent]) if recent else float("nan")
        print(
            f"iteration {iteration + 1}: team return {mean_return:8.1f}, success {success:.2f} "
            f"({len(finished)} episodes), entropy {stats['entropy']:.3f}, "
            f"{t_max * e * n / sampled:,.0f} agent-steps/s sampling, "
            f"{time.perf_counter() - started:.1f} s"
        )


if __name__ == "__main__":
    main()
