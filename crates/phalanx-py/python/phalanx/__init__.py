"""phalanx from Python: multi-agent path finding in formation over the Rust core.

- ``parallel_env(...)``: a PettingZoo ``ParallelEnv`` (every agent observes, then the joint
  action);
- ``vector_env(num_envs, ...)``: a ``gymnasium.vector.VectorEnv`` of ``num_envs`` teams
  stepped in one call in Rust, every output a NumPy array ``(num_envs, agents, ...)``;
- ``env(...)``: the turn-by-turn ``AECEnv`` in leader order, where each agent sees the
  actions already chosen this step by those before it (the paper's communication scheme);
- ``generate``, ``read_instance``, ``solve``, ``validate``: instances, every planner and
  learned solver by name, and the one validator with its metrics;
- ``load_policy("pathfinding" | "formation" | "e2e" | "ctce" | "imitation" | "hrl")``: the shipped policies, with an
  ``act(observations)`` that carries the recurrent state.

Bad input raises ``PhalanxError`` (a ``ValueError``) with the Rust message.
"""

from __future__ import annotations

from phalanx._phalanx import TEAM_DEADBAND, PhalanxError, default_formation_weight
from phalanx.envs import AECEnv, ParallelEnv, env, parallel_env
from phalanx.policies import load_policy
from phalanx.toolkit import Instance, Solution, generate, read_instance, solve, validate
from phalanx.vector import VectorEnv, vector_env

__all__ = [
    "AECEnv",
    "Instance",
    "ParallelEnv",
    "PhalanxError",
    "Solution",
    "TEAM_DEADBAND",
    "VectorEnv",
    "default_formation_weight",
    "env",
    "generate",
    "load_policy",
    "parallel_env",
    "read_instance",
    "solve",
    "validate",
    "vector_env",
]
