"""Environment steps per second through Python: phalanx's PettingZoo ParallelEnv and its
vectorised environment against POGEMA's own API, and phalanx's Rust-only `phalanx sim`, on
the same settings.

Random actions are drawn with numpy, observations come back every step, episodes restart
when they end (the vectorised environment restarts them itself, in the step). Each backend
runs in its own interpreter (POGEMA lives in a virtualenv of its own), and the driver
interleaves them round by round, so a drift of the machine hits every backend alike; it
prints each round and the medians and median ratios.

    # one measurement, in the interpreter that has the backend installed
    python bench_steps.py measure --backend phalanx --agents 3 --size 32 --density 0.15
    python bench_steps.py measure --backend vector --num-envs 256 --threads 1
    # the comparison, interleaved
    python bench_steps.py compare --phalanx-python venv/bin/python \\
        --pogema-python venv-pogema/bin/python --phalanx-bin target/release/phalanx \\
        --num-envs 64,256 --vector-threads 1,2
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


def measure_vector(
    agents: int, size: int, density: float, steps: int, num_envs: int, threads: int | None
) -> float:
    import numpy as np

    import phalanx

    env = phalanx.vector_env(
        num_envs, size=size, density=density, agents=agents, seed=1, num_threads=threads
    )
    rng = np.random.default_rng(0)
    env.reset()
    done = 0
    start = time.perf_counter()
    while done < steps:
        actions = rng.integers(0, 5, size=(num_envs, agents))
        obs, rewards, terminations, truncations, infos = env.step(actions)
        done += 1
    return done * num_envs * agents / (time.perf_counter() - start)


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
    one.add_argument("--backend", choices=["phalanx", "vector", "pogema"], required=True)
    one.add_argument("--agents", type=int, default=3)
    one.add_argument("--size", type=int, default=32)
    one.add_argument("--density", type=float, default=0.15)
    one.add_argument("--steps", type=int, default=20000)
    one.add_argument("--num-envs", type=int, default=256, help="vector: environments per step")
    one.add_argument("--threads", type=int, default=None, help="vector: threads (default all)")
    both = sub.add_parser("compare")
    both.add_argument("--phalanx-python", required=True)
    both.add_argument("--pogema-python", required=True)
    both.add_argument("--phalanx-bin", default=None,
                      help="the phalanx binary, for `phalanx sim` (left out: not measured)")
    both.add_argument("--baseline-python", default=None,
                      help="another build of phalanx (an interpreter that has it): its vector is "
                      "measured too, interleaved, as baseline_*")
    both.add_argument("--rounds", type=int, default=5)
    both.add_argument("--steps", type=int, default=20000)
    both.add_argument("--num-envs", default="256",
                      help="comma-separated environment counts, one vector measurement each")
    both.add_argument("--vector-steps", type=int, default=1000,
                      help="steps of a vector of 256 environments (scaled to others)")
    both.add_argument("--vector-threads", default="1",
                      help="comma-separated thread counts, one vector measurement each")
    both.add_argument("--settings", default=None,
                      help="agents:size:density,... (default the two of docs/python.md)")
    args = parser.parse_args()
    if args.command == "measure":
        if args.backend == "vector":
            rate = measure_vector(args.agents, args.size, args.density, args.steps,
                                  args.num_envs, args.threads)
        else:
            measure = measure_phalanx if args.backend == "phalanx" else measure_pogema
            rate = measure(args.agents, args.size, args.density, args.steps)
        print(json.dumps({"agent_steps_per_s": rate}))
        return
    settings = SETTINGS
    if args.settings:
        settings = [
            {"agents": int(a), "size": int(s), "density": float(d)}
            for a, s, d in (item.split(":") for item in args.settings.split(","))
        ]
    threads = [int(t) for t in args.vector_threads.split(",") if t]
    num_envs = [int(n) for n in args.num_envs.split(",") if n]
    for setting in settings:
        flags = ["--agents", str(setting["agents"]), "--size", str(setting["size"]),
                 "--density", str(setting["density"])]
        runs = [("phalanx", args.phalanx_python, ["--steps", str(args.steps)]),
                ("pogema", args.pogema_python, ["--steps", str(args.steps)])]
        # Every vector measurement makes about the same number of agent-steps.
        runs += [
            (f"vector_{n}x{t}t", args.phalanx_python,
             ["--backend", "vector", "--steps", str(max(1, args.vector_steps * 256 // n)),
              "--num-envs", str(n), "--threads", str(t)])
            for n in num_envs for t in threads
        ]
        if args.baseline_python:
            runs += [
                (f"baseline_{name}", args.baseline_python, extra)
                for name, _, extra in list(runs) if name.startswith("vector")
            ]
        rates: dict[str, list[float]] = {name: [] for name, _, _ in runs}
        if args.phalanx_bin:
            rates["sim"] = []
        for r in range(args.rounds):
            for backend, python, extra in runs:
                vector = backend.startswith(("vector", "baseline"))
                backend_flag = [] if vector else ["--backend", backend]
                out = subprocess.run(
                    [python, __file__, "measure", *backend_flag, *flags, *extra],
                    check=True, capture_output=True, text=True,
                )
                rates[backend].append(json.loads(out.stdout)["agent_steps_per_s"])
            if args.phalanx_bin:
                rates["sim"].append(measure_sim(args.phalanx_bin, setting["agents"],
                                                setting["size"], setting["density"], args.steps))
            print(f"{setting} round {r}: " + ", ".join(f"{k} {v[-1]:.3g}" for k, v in rates.items()),
                  file=sys.stderr)
        def median_ratio(a: str, b: str) -> float:
            return statistics.median(x / y for x, y in zip(rates[a], rates[b]))

        print(json.dumps({
            **setting,
            "rounds": args.rounds,
            "median_agent_steps_per_s": {k: statistics.median(v) for k, v in rates.items()},
            "median_ratio_over_pogema": {
                k: median_ratio(k, "pogema") for k in rates if k != "pogema"
            },
            **({"median_ratio_sim_over_phalanx_python": median_ratio("sim", "phalanx")}
               if args.phalanx_bin else {}),
        }))


if __name__ == "__main__":
    main()
