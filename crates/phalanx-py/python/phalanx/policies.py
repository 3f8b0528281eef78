"""The shipped policies from Python.

``load_policy(name)`` gives a policy whose ``act(observations)`` takes the observation dict
of a phalanx environment (``{agent: {"obstacles", "agents", "cost", "formation", "goal",
"action_mask", "message", "rank"}}``, and ``"place"`` and ``"team"`` for the planners'
student, which reads them: ``parallel_env(task="meta", place_vector=True, team_vector=True)``)
and returns ``{agent: action}``. Agents choose in the
order of their ``rank``, each with the actions of those before it as its message, so the
parallel form plays exactly as the turn-by-turn one. The recurrent state is carried from
call to call: ``reset()`` at the start of every episode.
"""

from __future__ import annotations

import os
import numpy as np

from phalanx import _phalanx
from phalanx.envs import CHANNELS, world_of

# The vectors a network reads, in order: 3 values each (its ``vector_len`` / 3 of them).
VECTOR_KEYS = ("goal", "place", "team")

Observations = dict[str, dict[str, np.ndarray]]


class Policy:
    """A learned policy of the five moves (``pathfinding``, ``formation``, ``e2e``,
    ``ctce`` or ``imitation``)."""

    def __init__(self, name: str, weights: str | os.PathLike | None = None) -> None:
        self.name = name
        self._net = _phalanx.Policy(name, None if weights is None else os.fspath(weights))

    @property
    def n_agents_max(self) -> int:
        return self._net.n_agents_max

    @property
    def vector_len(self) -> int:
        """The vector the network reads: 3 (goal), 6 (and place) or 9 (and team)."""
        return self._net.vector_len

    @property
    def team_deadband(self) -> float:
        """The team vector's dead band it acts at: its file's (1.5 unless it says otherwise), or
        for a student loaded as ``"imitation"`` the planners' student's test-time band, 0.3:
        act in ``parallel_env(..., team_deadband=policy.team_deadband)``."""
        return self._net.team_deadband

    @property
    def escape(self) -> str | None:
        """The stall escape it acts with, ``"VISITS:PROB"`` (from the VISITS-th step on one
        cell off its goal an agent takes a random allowed action with probability PROB), or
        ``None``: the ``imitation`` student's is ``"4:0.5"``, the others act greedily as
        trained. Set ``"off"`` or another ``"VISITS:PROB"``."""
        return self._net.escape

    @escape.setter
    def escape(self, escape: str | None) -> None:
        self._net.escape = escape

    def reset(self) -> None:
        """Forgets the recurrent state and the cells seen (a new episode)."""
        self._net.reset()

    def act(self, observations: Observations, epsilon: float = 0.0) -> dict[str, int]:
        """Every agent's action, greedy among the allowed ones (or ε-greedy), or the stall
        escape's random one (``escape``)."""
        names = list(observations)
        obs = [observations[name] for name in names]
        grid = np.ascontiguousarray(
            np.stack([np.stack([o[c] for c in CHANNELS]) for o in obs]), dtype=np.float32
        )
        keys = VECTOR_KEYS[: self._net.vector_len // 3]
        if any(key not in o for o in obs for key in keys):
            flags = ", ".join(f"{key}_vector=True" for key in keys[1:])
            raise _phalanx.PhalanxError(
                f"{self.name}: the policy reads the vectors {', '.join(keys)}: observations "
                f"of parallel_env(task='meta', {flags})"
            )
        rows = [np.concatenate([o[key] for key in keys]) for o in obs]
        vector = np.ascontiguousarray(np.stack(rows), dtype=np.float32)
        mask = np.ascontiguousarray(np.stack([o["action_mask"] for o in obs]), dtype=np.int8)
        rank = np.ascontiguousarray([int(o["rank"]) for o in obs], dtype=np.int64)
        actions = self._net.act(grid, vector, mask, rank, epsilon)
        return dict(zip(names, actions))


class HierarchicalPolicy:
    """The paper's method: the meta policy choosing path finding or formation per agent and
    step over the two frozen policies. Its formation frame is placed on the team's
    positions, so it reads the world the observations view (they must come from a phalanx
    environment, stepped with the actions returned; it keeps its own copy of the episode and
    refuses a world that took other actions)."""

    def __init__(self, weights: str | os.PathLike | None = None) -> None:
        self.name = "hrl"
        self._net = _phalanx.Hierarchy(None if weights is None else os.fspath(weights))

    def reset(self) -> None:
        self._net.reset()

    @property
    def choices(self) -> list[int]:
        """Each agent's low-level policy in the last step: 0 path finding, 1 formation."""
        return self._net.choices

    def act(self, observations: Observations) -> dict[str, int]:
        world = next((world_of(o) for o in observations.values()), None)
        if world is None:
            raise _phalanx.PhalanxError(
                "hrl acts on the observations of a phalanx environment (it reads their world)"
            )
        actions = self._net.act(world)
        names = [f"agent_{i}" for i in range(world.n_agents)]
        return {name: a for name, a in zip(names, actions) if name in observations}


def load_policy(
    name: str, weights: str | os.PathLike | None = None
) -> Policy | HierarchicalPolicy:
    """A shipped policy (``models/<name>``) or the one in ``weights``: ``pathfinding``,
    ``formation``, ``e2e``, ``ctce`` (the centralised baseline: it acts for the whole team at
    once), ``imitation`` (the student of the centralised expert, on the meta task's
    observations) or ``hrl`` (the hierarchy over the low level it was trained over)."""
    if name == "hrl":
        return HierarchicalPolicy(weights)
    if name not in ("pathfinding", "formation", "e2e", "ctce", "imitation"):
        raise _phalanx.PhalanxError(
            f"policy {name!r}: pathfinding, formation, e2e, ctce, imitation or hrl"
        )
    return Policy(name, weights)
