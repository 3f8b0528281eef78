"""Instances, solvers and the validator from Python.

A plan is one path per agent, each a list of ``(x, y)`` cells from the start; a path that
ends early waits at its last cell (libMultiRobotPlanning's convention).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Any

from phalanx import _phalanx
from phalanx._phalanx import Instance

Plan = list[list[tuple[int, int]]]


@dataclass
class Solution:
    """One run of a solver: ``outcome`` (``solved``, ``timeout``, ``unsolvable``,
    ``incomplete``, ``step-limit``, …), the ``plan`` when one came back, its ``metrics``
    (makespan, sum of costs, the paper's formation loss, …) and the whole ``summary``
    ``phalanx solve --json`` prints."""

    outcome: str
    plan: Plan | None
    metrics: dict[str, Any] | None
    summary: dict[str, Any]

    @property
    def solved(self) -> bool:
        return self.outcome == "solved"


def generate(
    size: int = _phalanx.DEFAULT_SIZE,
    density: float = _phalanx.DEFAULT_DENSITY,
    agents: int = _phalanx.DEFAULT_AGENTS,
    seed: int = 0,
    fov: int = _phalanx.DEFAULT_FOV,
) -> Instance:
    """The paper's generator: the instance ``phalanx gen`` writes for these settings."""
    return _phalanx.generate(size, density, agents, seed, fov)


def read_instance(path: str | os.PathLike, agents: int | None = None) -> Instance:
    """A libMultiRobotPlanning ``.yaml`` instance or a MovingAI ``.scen`` (its first
    ``agents`` entries, on the map it names)."""
    return _phalanx.read_instance(os.fspath(path), agents)


def solve(
    instance: Instance | str | os.PathLike,
    planner: str = "cbs",
    time_limit: float = 60.0,
    rollouts: int = 8,
    seed: int = 0,
    keep: str | None = None,
) -> Solution:
    """Solves ``instance`` (or the instance file at that path) with ``planner``: ``cbs``,
    ``ecbs[:W]``, ``astar``, ``swarm``, ``jsa[:W]``, or the learned ``pathfinding``,
    ``leader[:L]``, ``hrl[:M]``, ``e2e``, ``imitation`` (shipped models; ``rollouts``
    test-time rollouts, of which by default (``keep=None``) the method's own rule picks one:
    the fastest, and for ``imitation`` the tightest within 1.1 × the makespan's lower bound
    (every rollout at its test-time dead band 0.3, those after the first sampled at the
    temperature 0.5 on an instance a rollout solved; ``imitation:second=0`` plays the second
    greedily at the band 0, ``imitation:temp=none`` the later ones greedily with random
    actions);
    ``keep="fastest"``, ``"tightest"`` or ``"within:BUDGET"`` for another rule)."""
    if not isinstance(instance, Instance):
        instance = read_instance(instance)
    summary_json, plan = _phalanx.solve(
        instance, planner, float(time_limit), rollouts, seed, keep
    )
    summary = json.loads(summary_json)
    return Solution(summary["outcome"], plan, summary.get("metrics"), summary)


def validate(instance: Instance, plan: Plan) -> tuple[str | None, dict[str, Any]]:
    """The one validator: the first violation (``None`` when the plan is valid) and the
    plan's metrics, whoever made the plan."""
    violation, metrics = _phalanx.validate(instance, [list(map(tuple, p)) for p in plan])
    return violation, json.loads(metrics)
