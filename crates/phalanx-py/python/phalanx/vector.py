"""The vectorised environment: ``num_envs`` teams stepped in one call in Rust.

``vector_env(num_envs, ...)`` is a ``gymnasium.vector.VectorEnv`` over
``phalanx._phalanx.VecWorld``. Gymnasium's vector API is for one agent per environment; a
phalanx environment is a team of ``agents``, so every array carries both axes:

- ``reset(seed=None, options=None) -> (observations, infos)``;
- ``step(actions) -> (observations, rewards, terminations, truncations, infos)`` with
  ``actions`` an integer array ``(num_envs, agents)`` (up, down, left, right, wait);
- ``observations``: a dict of the single environment's keys, each array ``(num_envs,
  agents, ...)``; ``rewards`` ``(num_envs, agents)`` f32 (each agent's own reward; the team
  reward is ``rewards.sum(1)``); ``terminations``, ``truncations`` ``(num_envs, agents)``
  bool (the team ends together, so an environment's row is all one value);
- infos: ``formation_loss`` ``(num_envs,)``, ``cancelled`` and ``on_goal`` ``(num_envs,
  agents)``, ``seed`` ``(num_envs,)`` (each environment's running episode), and the
  auto-reset's ``final_obs`` (a dict like ``observations``) with its mask ``_final_obs``.

Auto-reset is Gymnasium's ``SAME_STEP`` mode: an environment whose episode ends this step
starts its next episode at once, so the returned observation is the new episode's first and
every row can be acted on; the ended episode's last observation is in
``infos["final_obs"]``, valid in the rows where ``infos["_final_obs"]`` is true (other
rows hold older contents). Rewards and flags are those of the step that ended the episode.

Every returned array is the same object every step, overwritten in place by the next
``step`` (nothing is copied or allocated per step): copy what you keep (a rollout buffer
does). The views are read-only.

Seeding: environment ``i`` of a vector seeded ``s`` plays exactly what
``parallel_env(seed=(s + i * 2**32) % 2**64)`` plays, episode after episode (auto-resets take
the seed after the last one, as the single environment's reset without a seed does);
``reset(seed=[s_0, ..., s_{N-1}])`` seeds each environment on its own. Environment 0 is the
single environment of the same seed. Without any seed the first is drawn from the
operating system.
"""

from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from gymnasium.vector import VectorEnv as _VectorEnv
from gymnasium.vector.utils import batch_space

from phalanx import _phalanx
from phalanx.envs import ACTIONS, CHANNELS

_SEED_MASK = (1 << 64) - 1
#: Seeds between consecutive environments of a vector: each plays ``2**32`` episodes before
#: it would reach the next one's first.
ENV_SEED_STRIDE = 1 << 32


def env_seeds(seed: int, num_envs: int) -> list[int]:
    """The first seed of each environment of a vector seeded ``seed``."""
    return [(seed + i * ENV_SEED_STRIDE) & _SEED_MASK for i in range(num_envs)]


class VectorEnv(_VectorEnv):
    """``num_envs`` phalanx environments of one setting, stepped together in Rust (see the
    module docs)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int,
        size: int = _phalanx.DEFAULT_SIZE,
        density: float = _phalanx.DEFAULT_DENSITY,
        agents: int = _phalanx.DEFAULT_AGENTS,
        task: str = "pathfinding",
        fov: int = _phalanx.DEFAULT_FOV,
        formation_weight: float | None = None,
        seed: int | None = None,
        instance: str | os.PathLike | None = None,
        num_threads: int | None = None,
    ) -> None:
        path = None if instance is None else os.fspath(instance)
        weight = 1.0 if formation_weight is None else float(formation_weight)
        self.world = _phalanx.VecWorld(
            num_envs, size, density, agents, task, fov, weight, path, num_threads
        )
        n = self.world.n_agents
        if task == "meta" and formation_weight is None:
            self.world.set_formation_weight(_phalanx.default_formation_weight(n))
        self.num_envs = num_envs
        self.n_agents = n
        self.task = task
        self.render_mode = None
        self._next_seeds: list[int] | None = None if seed is None else env_seeds(seed, num_envs)
        self._started = False
        f = self.world.fov
        self.single_observation_space = spaces.Dict(
            {
                "obstacles": spaces.Box(0.0, 1.0, (n, f, f), np.float32),
                "agents": spaces.Box(0.0, 1.0, (n, f, f), np.float32),
                "cost": spaces.Box(-1.0, 2.0, (n, f, f), np.float32),
                "formation": spaces.Box(0.0, 1.0, (n, f, f), np.float32),
                "goal": spaces.Box(
                    np.tile(np.array([-1, -1, 0], np.float32), (n, 1)),
                    np.tile(np.array([1, 1, 1], np.float32), (n, 1)),
                ),
                "action_mask": spaces.Box(0, 1, (n, len(ACTIONS)), np.int8),
                "message": spaces.Box(0.0, 1.0, (n, n, len(ACTIONS)), np.float32),
                "rank": spaces.MultiDiscrete([n] * n),
            }
        )
        self.single_action_space = spaces.MultiDiscrete([len(ACTIONS)] * n)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._obs = _views(self.world.grid, self.world.vector, self.world.action_mask,
                           self.world.rank, n)
        self._rewards = _read_only(self.world.rewards)
        self._terminations = _read_only(self.world.terminated)
        self._truncations = _read_only(self.world.truncated)
        final_obs = _views(self.world.final_grid, self.world.final_vector,
                           self.world.final_action_mask, self.world.final_rank, n)
        self._infos = {
            "formation_loss": _read_only(self.world.formation_loss),
            "cancelled": _read_only(self.world.cancelled),
            "on_goal": _read_only(self.world.on_goal),
            "seed": _read_only(self.world.seed),
            "final_obs": final_obs,
            "_final_obs": _read_only(self.world.ended),
        }

    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Starts an episode in every environment: ``seed`` an int (environment ``i`` plays
        ``seed + i * 2**32``), one seed per environment, or ``None`` (each environment's next
        seed); returns the observations and the infos of ``step`` (no step yet: no reward,
        flag or cancelled move; the episodes' first ``formation_loss`` and ``on_goal``)."""
        if seed is None:
            seeds = self._next_seeds
            if seeds is None and not self._started:
                seeds = env_seeds(int.from_bytes(os.urandom(8), "little"), self.num_envs)
        elif isinstance(seed, (int, np.integer)):
            seeds = env_seeds(int(seed), self.num_envs)
        else:
            seeds = [int(s) & _SEED_MASK for s in seed]
        self.world.reset(seeds)
        self._next_seeds = None
        self._started = True
        return self._obs, self._infos

    def step(self, actions: Any):
        """Steps every environment with its row of ``actions`` (``(num_envs, agents)``
        integers); ended episodes restart at once (see the module docs)."""
        actions = np.asarray(actions)
        if actions.dtype != np.int64 or not actions.flags.c_contiguous:
            if actions.dtype.kind not in "iu":
                raise _phalanx.PhalanxError(
                    f"actions of dtype {actions.dtype}: integers (action indices 0..5)"
                )
            actions = np.ascontiguousarray(actions, dtype=np.int64)
        self.world.step(actions)
        return self._obs, self._rewards, self._terminations, self._truncations, self._infos

    def close_extras(self, **kwargs: Any) -> None:
        pass


def _read_only(array: np.ndarray) -> np.ndarray:
    view = array.view()
    view.flags.writeable = False
    return view


def _views(grid, vector, mask, rank, n: int) -> dict[str, np.ndarray]:
    """The single environment's observation keys as read-only views of the vector's
    arrays, each ``(num_envs, agents, ...)``."""
    num_envs = grid.shape[0]
    views = {c: _read_only(grid[:, :, k]) for k, c in enumerate(CHANNELS)}
    views["goal"] = _read_only(vector)
    views["action_mask"] = _read_only(mask)
    # The parallel form's messages are zero: no agent has acted when it observes.
    views["message"] = np.broadcast_to(np.zeros((), np.float32), (num_envs, n, n, len(ACTIONS)))
    views["rank"] = _read_only(rank)
    return views


def vector_env(num_envs: int, **kwargs: Any) -> VectorEnv:
    """A ``VectorEnv`` of ``num_envs`` environments with ``parallel_env``'s settings
    (``size``, ``density``, ``agents``, ``task``, ``fov``, ``formation_weight``, ``seed``,
    ``instance``; no rendering) and ``num_threads``, the threads that step them, the
    calling one included (``1``: the calling thread alone; ``None``: as many as rayon's
    global pool has, ``RAYON_NUM_THREADS`` or one thread per core)."""
    return VectorEnv(num_envs, **kwargs)
