"""The PettingZoo environments over ``phalanx._phalanx.World``.

Observations are per agent a ``dict`` of NumPy arrays that *view* the Rust environment's
buffers: the world writes each step straight into them, no copy is made, and the same
arrays come back every step with new contents. Copy one (``np.copy``) to keep it past the
next step. The views are read-only.

Agents all finish together: the team's episode ends when every agent stands on its goal
(path finding, meta), when the team is in formation (formation) or at the step limit
(``3 ×`` the map side); an agent on its goal stays in the world, since it may have to step
aside for the others. So ``agents`` is the full team until the episode ends, then empty.

Seeding: ``reset(seed=s)`` plays the generator's instance of seed ``s`` (the map
``phalanx gen --seed s`` writes); later resets without a seed play ``s + 1``, ``s + 2``, …
Without any seed the first one is drawn from the operating system.
"""

from __future__ import annotations

import functools
import os
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import AECEnv as _AECEnv
from pettingzoo import ParallelEnv as _ParallelEnv

from phalanx import _phalanx

#: Action indices: the four moves and waiting.
ACTIONS = ("up", "down", "left", "right", "wait")
CHANNELS = ("obstacles", "agents", "cost", "formation")
RENDER_MODES = ("ansi", "rgb_array", "svg")
_SEED_MASK = (1 << 64) - 1

class AgentObservation(dict):
    """One agent's observation: a ``dict`` of array views, which also names the ``world``
    it views (a policy given only observations finds the world there; the hierarchy
    needs it)."""

    __slots__ = ("world",)

    def _copied(self) -> dict[str, np.ndarray]:
        return {key: np.copy(value) for key, value in self.items()}

    def __deepcopy__(self, memo: dict) -> dict[str, np.ndarray]:
        # A copy is a plain dict of copied arrays: it no longer views the world.
        return self._copied()

    def __reduce__(self):
        return (dict, (self._copied(),))


def world_of(observation: dict[str, np.ndarray]) -> "_phalanx.World | None":
    """The world whose buffers ``observation`` (one agent's) views, if any."""
    return getattr(observation, "world", None)


class _Core:
    """The world, its agents' names and observation views, and the seeding rule."""

    def __init__(
        self,
        size: int,
        density: float,
        agents: int,
        task: str,
        fov: int,
        formation_weight: float | None,
        seed: int | None,
        instance: str | os.PathLike | None,
        render_mode: str | None,
        place_vector: bool,
        team_vector: bool,
        team_deadband: float,
    ) -> None:
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise _phalanx.PhalanxError(
                f"render_mode {render_mode!r}: one of {', '.join(RENDER_MODES)} or None"
            )
        path = None if instance is None else os.fspath(instance)
        weight = 1.0 if formation_weight is None else float(formation_weight)
        vectors = (bool(place_vector), bool(team_vector))
        self.world = _phalanx.World(
            size, density, agents, task, fov, weight, path, *vectors, float(team_deadband)
        )
        if task == "meta" and formation_weight is None:
            n = self.world.n_agents
            self.world.set_formation_weight(_phalanx.default_formation_weight(n))
        self.task = task
        self.render_mode = render_mode
        self.next_seed = None if seed is None else seed & _SEED_MASK
        n = self.world.n_agents
        f = self.world.fov
        # The world's own name objects: the keys of the dicts its parallel step builds.
        self.names = list(self.world.agent_names)
        grid, vector = self.world.grid, self.world.vector
        mask, message, rank = self.world.action_mask, self.world.message, self.world.rank
        self.rewards = self.world.rewards
        self.obs: dict[str, AgentObservation] = {}
        for i, name in enumerate(self.names):
            views = {c: grid[i, k] for k, c in enumerate(CHANNELS)}
            views["goal"] = vector[i, :3]
            if place_vector:
                views["place"] = vector[i, 3:6]
            if team_vector:
                views["team"] = vector[i, 6:9]
            views["action_mask"] = mask[i]
            views["message"] = message[i]
            views["rank"] = rank[i : i + 1].reshape(())
            for view in views.values():
                view.flags.writeable = False
            observation = AgentObservation(views)
            observation.world = self.world
            self.obs[name] = observation
        grid_box = spaces.Box(0.0, 1.0, (f, f), np.float32)
        vector_box = spaces.Box(
            np.array([-1, -1, 0], np.float32), np.array([1, 1, 1], np.float32)
        )
        observation_space = {
            "obstacles": grid_box,
            "agents": spaces.Box(0.0, 1.0, (f, f), np.float32),
            "cost": spaces.Box(-1.0, 2.0, (f, f), np.float32),
            "formation": spaces.Box(0.0, 1.0, (f, f), np.float32),
            "goal": vector_box,
            "action_mask": spaces.Box(0, 1, (len(ACTIONS),), np.int8),
            "message": spaces.Box(0.0, 1.0, (n, len(ACTIONS)), np.float32),
            "rank": spaces.Discrete(n),
        }
        if place_vector:
            observation_space["place"] = vector_box
        if team_vector:
            observation_space["team"] = vector_box
        self.observation_space = spaces.Dict(observation_space)
        self.action_space = spaces.Discrete(len(ACTIONS))

    def reset(self, seed: int | None) -> None:
        if seed is not None:
            self.next_seed = seed & _SEED_MASK
        elif self.next_seed is None:
            self.next_seed = int.from_bytes(os.urandom(8), "little")
        self.world.reset(self.next_seed)
        self.next_seed = (self.next_seed + 1) & _SEED_MASK

    def info(self, formation_loss: float, cancelled: list[bool]) -> dict[str, dict[str, Any]]:
        on_goal = self.world.on_goal
        return {
            name: {
                "formation_loss": formation_loss,
                "cancelled": cancelled[i],
                "on_goal": on_goal[i],
            }
            for i, name in enumerate(self.names)
        }

    def render(self) -> Any:
        if self.render_mode == "ansi":
            return self.world.render_text()
        if self.render_mode == "svg":
            return self.world.render_svg()
        if self.render_mode == "rgb_array":
            return self.world.render_rgb()
        return None


class _Shared:
    """What both forms share: the world and its agents' names, the spaces, rendering."""

    def _setup(
        self,
        size: int = _phalanx.DEFAULT_SIZE,
        density: float = _phalanx.DEFAULT_DENSITY,
        agents: int = _phalanx.DEFAULT_AGENTS,
        task: str = "pathfinding",
        fov: int = _phalanx.DEFAULT_FOV,
        formation_weight: float | None = None,
        seed: int | None = None,
        instance: str | os.PathLike | None = None,
        render_mode: str | None = None,
        place_vector: bool = False,
        team_vector: bool = False,
        team_deadband: float = _phalanx.TEAM_DEADBAND,
    ) -> None:
        self._core = _Core(
            size,
            density,
            agents,
            task,
            fov,
            formation_weight,
            seed,
            instance,
            render_mode,
            place_vector,
            team_vector,
            team_deadband,
        )
        self.render_mode = render_mode
        self.possible_agents = list(self._core.names)

    @property
    def world(self) -> _phalanx.World:
        """The Rust environment: positions, instance, trajectory, formation loss."""
        return self._core.world

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent: str) -> spaces.Space:
        return self._core.observation_space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str) -> spaces.Space:
        return self._core.action_space

    def render(self) -> Any:
        return self._core.render()

    def close(self) -> None:
        pass


class ParallelEnv(_Shared, _ParallelEnv):
    """Every agent observes, then the world takes the joint action (see the module docs).

    The ``message`` of each observation is zero here, since no agent has acted when the
    observations are made; ``rank`` is each agent's place in this step's leader order, by
    which a policy's ``act`` lets agents choose in turn (``env()`` shows the messages).
    """

    metadata = {"name": "phalanx_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(self, **settings: Any) -> None:
        self._setup(**settings)
        self.agents: list[str] = []
        self._step_parallel = self._core.world.step_parallel

    def reset(self, seed: int | None = None, options: dict | None = None):
        self._core.reset(seed)
        self.agents = list(self.possible_agents)
        obs = dict(self._core.obs)
        infos = {name: {} for name in self.agents}
        return obs, infos

    def step(self, actions: dict[str, int]):
        if not self.agents:
            raise _phalanx.PhalanxError("the episode has ended: reset first")
        # One call: the world reads the actions, steps, writes the observations and builds
        # the rewards, flags and infos dicts (an agent left out of ``actions`` waits).
        if type(actions) is not dict:
            actions = dict(actions)
        out = self._step_parallel(actions, self._core.obs)
        if self._core.world.done:
            self.agents = []
        return out

    def state(self) -> np.ndarray:
        """The agents' cells, ``[N, 2]`` ``(x, y)``."""
        return np.array(self._core.world.positions, dtype=np.int64)


class AECEnv(_Shared, _AECEnv):
    """Agents act one at a time in the step's leader order; each observes the actions chosen
    before it this step as its ``message``, and the world moves once every agent has chosen
    (rewards then come to every agent at once)."""

    metadata = {"name": "phalanx_aec_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(self, **settings: Any) -> None:
        super().__init__()
        self._setup(**settings)
        self.agents = []
        self.rewards = {}
        self._cumulative_rewards = {}
        self.terminations = {}
        self.truncations = {}
        self.infos = {}
        self.agent_selection = self.possible_agents[0]

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        self._core.reset(seed)
        self.agents = list(self.possible_agents)
        self.rewards = dict.fromkeys(self.agents, 0.0)
        self._cumulative_rewards = dict.fromkeys(self.agents, 0.0)
        self.terminations = dict.fromkeys(self.agents, False)
        self.truncations = dict.fromkeys(self.agents, False)
        self.infos = {name: {} for name in self.agents}
        self.agent_selection = self.possible_agents[self._core.world.current_agent]

    def observe(self, agent: str) -> dict[str, np.ndarray]:
        return self._core.obs[agent]

    def step(self, action: int | None) -> None:
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        if action is None:
            raise _phalanx.PhalanxError(f"{agent}: an action is needed while it is alive")
        self._cumulative_rewards[agent] = 0.0
        out = self._core.world.choose(int(action))
        if out is None:
            self._clear_rewards()
            self.agent_selection = self.possible_agents[self._core.world.current_agent]
        else:
            terminated, truncated, formation_loss, cancelled = out
            self.rewards = dict(zip(self.agents, self._core.rewards.tolist()))
            self.infos = self._core.info(formation_loss, cancelled)
            if terminated or truncated:
                self.terminations = dict.fromkeys(self.agents, terminated)
                self.truncations = dict.fromkeys(self.agents, truncated and not terminated)
                self._deads_step_first()
            else:
                self.agent_selection = self.possible_agents[self._core.world.current_agent]
        self._accumulate_rewards()


def parallel_env(**kwargs: Any) -> ParallelEnv:
    """A ``ParallelEnv``: ``size=32, density=0.15, agents=3, task="pathfinding"`` (or
    ``"formation"``, ``"meta"``), ``fov=9``, ``formation_weight=None`` (the meta task's
    ``w_f`` of Eq. 14 for the team size), ``seed=None``, ``instance=None`` (a
    libMultiRobotPlanning ``.yaml`` or MovingAI ``.scen`` path, played every episode),
    ``render_mode=None`` (``"ansi"``, ``"rgb_array"`` or ``"svg"``), ``place_vector=False``
    (meta task only: each observation gains ``"place"``, the vector towards the agent's
    place in the goal layout placed on the agent in front), ``team_vector=False`` (with
    ``place_vector``: each observation gains ``"team"``, for the agent in front the vector
    towards its place in the goal layout placed on the team, zeros for the others),
    ``team_deadband=1.5`` (the team vector is zeros while shorter than this many cells; a
    student acts at ``load_policy("imitation").team_deadband``, the planners' student's
    test-time band 0.3; narrower, its teams keep their shape better and take longer,
    docs/imitation.md); the planners' student ``load_policy("imitation")`` reads
    both vectors."""
    return ParallelEnv(**kwargs)


def env(**kwargs: Any) -> AECEnv:
    """The turn-by-turn ``AECEnv`` in leader order, with ``parallel_env``'s arguments."""
    return AECEnv(**kwargs)
