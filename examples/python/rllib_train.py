"""A few PPO iterations of RLlib on phalanx's PettingZoo environment.

    pip install ./crates/phalanx-py "ray[rllib]" torch
    python examples/python/rllib_train.py --iterations 3

One policy is shared by every agent (the agents are interchangeable, as phalanx's own
learner shares its network). The Dict observation is flattened into one vector per agent by
RLlib's connector `FlattenObservations`. On a cluster, start Ray there (`ray start --head` on one machine, `ray start
--address=HEAD:6379` on the others), run this script on the head with `--address auto`
and raise `--env-runners` to the cores you have: each env runner steps its own copies of
the environment, and the learner gathers their samples.
"""

from __future__ import annotations

import argparse
import time

import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.connectors.env_to_module import FlattenObservations
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env

import phalanx


def make_env(config: dict) -> ParallelPettingZooEnv:
    return ParallelPettingZooEnv(
        phalanx.parallel_env(
            size=config.get("size", 20),
            density=config.get("density", 0.15),
            agents=config.get("agents", 3),
            task=config.get("task", "pathfinding"),
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--env-runners", type=int, default=1)
    parser.add_argument("--address", default=None, help="a Ray cluster (auto: the running one)")
    parser.add_argument("--size", type=int, default=20)
    parser.add_argument("--agents", type=int, default=3)
    args = parser.parse_args()

    ray.init(address=args.address, include_dashboard=False)
    register_env("phalanx", make_env)
    env_config = {"size": args.size, "agents": args.agents}
    probe = make_env(env_config)
    agents = list(probe.possible_agents)
    config = (
        PPOConfig()
        .environment("phalanx", env_config=env_config)
        .framework("torch")
        .env_runners(
            num_env_runners=args.env_runners,
            # The Dict observation becomes one vector per agent (rank one-hot).
            env_to_module_connector=lambda *_, **__: FlattenObservations(multi_agent=True),
        )
        .training(train_batch_size=2000, minibatch_size=250, num_epochs=4, lr=3e-4)
        .multi_agent(
            policies={"shared"},
            policy_mapping_fn=lambda agent_id, *_, **__: "shared",
        )
    )
    algo = config.build_algo()
    print(f"phalanx on RLlib: PPO, {len(agents)} agents sharing one policy, {args.size}² maps")
    for i in range(args.iterations):
        started = time.perf_counter()
        result = algo.train()
        runners = result.get("env_runners", {})
        print(
            f"iteration {i + 1}: "
            f"episode_return_mean {runners.get('episode_return_mean', float('nan')):.2f}, "
            f"episode_len_mean {runners.get('episode_len_mean', float('nan')):.1f}, "
            f"env_steps {result.get('num_env_steps_sampled_lifetime', 'n/a')}, "
            f"{time.perf_counter() - started:.1f} s"
        )
    algo.stop()
    ray.shutdown()


if __name__ == "__main__":
    main()
