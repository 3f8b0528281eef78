"""Environment steps per second through Python: phalanx's PettingZoo ParallelEnv against
POGEMA's own API, and phalanx's Rust-only `phalanx sim`, on the same settings.

Random actions are drawn with numpy, observations come back every step, episodes restart
when they end. Each backend runs in its own interpreter (POGEMA lives in a virtualenv of its
own), and the driver interleaves them round by round, so a drift of the machine hits every
backend alike; it prints each round and the medians and median ratios.

    # one measurement, in the interpreter that has the backend installed
    python bench_steps.py measure --backend phalanx --agents 3 --size 32 --density 0.15
    # the comparison, interleaved
    python bench_steps.py compare --phalanx-python venv/bin/python \\
        --pogema-python venv-pogema/bin/python --phalanx-bin target/release/phalanx
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time

SETTINGS = [
    {"agents": 3, "size": 32, "density": 0.15},
    {"agents": 25, "size": 64, "density": 0.3},
]


def measure_phalanx(agents: int, size: int, density: float, steps: int) -> float:
    import numpy as np

    import phalanx

    env = phalanx.parallel_env(size=size, density=density, agents=agents, seed=1)
    rng = np.random.default_rng(0)
    names = env.possible_agents
    env.reset(seed=1)
    done = 0
    start = time.perf_counter()
    while done < steps:
        actions = dict(zip(names, rng.integers(0, 5, size=len(names)).tolist()))
        obs, rewards, terminations, truncations, infos = env.step(actions)
        done += 1
        if not env.agents:
            env.reset()
    return done * agents / (time.perf_counter() - start)


def measure_pogema(agents: int, size: int, density: float, steps: int) -> float:
    import numpy as np
    from pogema import GridConfig, pogema_v0

    config = GridConfig(
        num_agents=agents,
        size=size,
        density=density,
        seed=1,
        max_episode_steps=3 * size,
        obs_radius=4,
    )
    env = pogema_v0(grid_config=config)
    rng = np.random.default_rng(0)
    env.reset()
    done = 0
    start = time.perf_counter()
    while done < steps:
        actions = rng.integers(0, 5, size=agents).tolist()
        obs, rewards, terminated, truncated, infos = env.step(actions)
        done += 1
        if all(terminated) or all(truncated):
            env.reset()
    return done * agents / (time.perf_counter() - start)


def measure_sim(binary: str, agents: int, size: int, density: float, steps: int) -> float:
    episodes = max(1, steps // (3 * size))
    out = subprocess.run(
        [binary, "sim", "--size", str(size), "--density", str(density), "--agents", str(agents),
         "--episodes", str(episodes), "--policy", "random", "--json"],
        check=True, capture_output=True, text=True,
    )
    return json.loads(out.stdout)["agent_steps_per_s"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    one = sub.add_parser("measure")
    one.add_argument("--backend", choices=["phalanx", "pogema"], required=True)
    one.add_argument("--agents", type=int, default=3)
    one.add_argument("--size", type=int, default=32)
    one.add_argument("--density", type=float, default=0.15)
    one.add_argument("--steps", type=int, default=20000)
    both = sub.add_parser("compare")
    both.add_argument("--phalanx-python", required=True)
    both.add_argument("--pogema-python", required=True)
    both.add_argument("--phalanx-bin", required=True)
    both.add_argument("--rounds", type=int, default=5)
    both.add_argument("--steps", type=int, default=20000)
    args = parser.parse_args()
    if args.command == "measure":
        measure = measure_phalanx if args.backend == "phalanx" else measure_pogema
        print(json.dumps({"agent_steps_per_s": measure(args.agents, args.size, args.density, args.steps)}))
        return
    for setting in SETTINGS:
        flags = ["--agents", str(setting["agents"]), "--size", str(setting["size"]),
                 "--density", str(setting["density"]), "--steps", str(args.steps)]
        rates: dict[str, list[float]] = {"phalanx": [], "pogema": [], "sim": []}
        for r in range(args.rounds):
            for backend, python in (("phalanx", args.phalanx_python), ("pogema", args.pogema_python)):
                out = subprocess.run(
                    [python, __file__, "measure", "--backend", backend, *flags],
                    check=True, capture_output=True, text=True,
                )
                rates[backend].append(json.loads(out.stdout)["agent_steps_per_s"])
            rates["sim"].append(measure_sim(args.phalanx_bin, setting["agents"], setting["size"],
                                            setting["density"], args.steps))
            print(f"{setting} round {r}: " + ", ".join(f"{k} {v[-1]:.3g}" for k, v in rates.items()),
                  file=sys.stderr)
        vs_pogema = [a / b for a, b in zip(rates["phalanx"], rates["pogema"])]
        sim_vs_py = [a / b for a, b in zip(rates["sim"], rates["phalanx"])]
        print(json.dumps({
            **setting,
            "rounds": args.rounds,
            "median_agent_steps_per_s": {k: statistics.median(v) for k, v in rates.items()},
            "median_ratio_phalanx_python_over_pogema": statistics.median(vs_pogema),
            "median_ratio_sim_over_phalanx_python": statistics.median(sim_vs_py),
        }))


if __name__ == "__main__":
    main()
