"""Tests of the Python package: PettingZoo's own API and seed tests, the observations against
the Rust environment and an encoding computed here, plans from Python through the one
validator, the shipped policies against `phalanx solve`, and bad input."""

from __future__ import annotations

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

import phalanx

ROOT = pathlib.Path(__file__).resolve().parents[3]


def phalanx_bin() -> str:
    """The `phalanx` binary of this checkout (built by the test command before pytest)."""
    if "PHALANX_BIN" in os.environ:
        return os.environ["PHALANX_BIN"]
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in ("debug", "release"):
        candidate = target / profile / "phalanx"
        if candidate.is_file():
            return str(candidate)
    raise RuntimeError(f"no phalanx binary under {target}: cargo build -p phalanx-cli first")


@pytest.fixture(scope="module")
def instance_file(tmp_path_factory) -> pathlib.Path:
    path = tmp_path_factory.mktemp("inst") / "seed7.yaml"
    subprocess.run([phalanx_bin(), "gen", "--seed", "7", "-o", str(path)], check=True)
    return path


@pytest.mark.parametrize("task", ["pathfinding", "formation", "meta"])
def test_parallel_api(task):
    parallel_api_test(phalanx.parallel_env(task=task, size=20), num_cycles=100)
    parallel_seed_test(lambda: phalanx.parallel_env(task=task, size=20))


def test_aec_api():
    api_test(phalanx.env(size=20), num_cycles=100)
    seed_test(lambda: phalanx.env(size=20))


def test_is_a_pettingzoo_env_whose_spaces_are_stable():
    import pettingzoo

    env = phalanx.parallel_env()
    assert isinstance(env, pettingzoo.ParallelEnv)
    assert isinstance(phalanx.env(), pettingzoo.AECEnv)
    env.reset(seed=1)
    for agent in env.possible_agents:
        assert env.observation_space(agent) is env.observation_space(agent)
        assert env.action_space(agent) is env.action_space(agent)
    env.render_mode = "ansi"  # PettingZoo's tests set attributes
    assert env.agents == env.possible_agents


def test_seed_plays_the_generators_instance_and_views_update_in_place(instance_file):
    by_seed = phalanx.parallel_env(seed=7)
    by_file = phalanx.parallel_env(instance=instance_file)
    obs_seed, _ = by_seed.reset(seed=7)
    obs_file, _ = by_file.reset()
    generated = phalanx.read_instance(instance_file)
    assert by_seed.world.instance.starts == generated.starts
    assert by_seed.world.instance.goals == generated.goals
    view = obs_seed["agent_0"]["cost"]
    first, start = np.copy(view), by_seed.world.positions
    rng = np.random.default_rng(3)
    for _ in range(20):
        for agent in by_seed.possible_agents:
            for key, value in obs_seed[agent].items():
                np.testing.assert_array_equal(value, obs_file[agent][key], err_msg=key)
        actions = {a: int(rng.integers(5)) for a in by_seed.agents}
        obs_seed, r_seed, *_ = by_seed.step(actions)
        obs_file, r_file, *_ = by_file.step(actions)
        assert r_seed == r_file
    # The arrays are views of the world's buffers: the same objects, new contents.
    assert obs_seed["agent_0"]["cost"] is view
    assert by_seed.world.positions != start and not np.array_equal(first, view)
    with pytest.raises(ValueError):
        obs_seed["agent_0"]["cost"][0, 0] = 1.0


def test_observation_encoding_matches_one_computed_here():
    env = phalanx.parallel_env(size=32, agents=3, fov=9)
    obs, _ = env.reset(seed=11)
    instance = env.world.instance
    blocked = instance.obstacles
    f, r = 9, 4
    for i, (x, y) in enumerate(env.world.positions):
        o = obs[f"agent_{i}"]
        # Row 0 of the window is the smallest y, column 0 the smallest x; outside is blocked.
        expected = np.ones((f, f), np.float32)
        for row in range(f):
            for col in range(f):
                cx, cy = x + col - r, y + row - r
                if 0 <= cx < instance.width and 0 <= cy < instance.height:
                    expected[row, col] = float(blocked[cy, cx])
        np.testing.assert_array_equal(o["obstacles"], expected)
        assert o["agents"][r, r] == pytest.approx((i + 1) / 3)
        gx, gy = instance.goals[i]
        d = np.hypot(gx - x, gy - y)
        np.testing.assert_allclose(o["goal"], [(gx - x) / d, (gy - y) / d, d / (d + f)], rtol=1e-6)
        assert o["action_mask"][4] == 1 and o["action_mask"].dtype == np.int8
        assert not o["message"].any()
    assert sorted(int(obs[a]["rank"]) for a in env.agents) == [0, 1, 2]


def test_turn_by_turn_messages_carry_the_earlier_actions():
    aec = phalanx.env(seed=5)
    aec.reset(seed=5)
    chosen = {}
    for k in range(3):
        agent = aec.agent_selection
        message = aec.observe(agent)["message"]
        assert int(aec.observe(agent)["rank"]) == k
        for earlier, action in chosen.items():
            row = message[int(earlier.split("_")[1])]
            assert row[action] == 1.0 and row.sum() == 1.0
        assert message.sum() == len(chosen)
        chosen[agent] = 4
        aec.step(4)
    assert aec.world.t == 1


def test_a_plan_solved_from_python_validates_and_is_scored_like_the_cli(instance_file):
    instance = phalanx.read_instance(instance_file)
    solution = phalanx.solve(instance, "cbs", time_limit=10)
    assert solution.solved
    violation, metrics = phalanx.validate(instance, solution.plan)
    assert violation is None
    cli = subprocess.run(
        [phalanx_bin(), "solve", str(instance_file), "--planner", "cbs", "--json"],
        check=True,
        capture_output=True,
        text=True,
    )
    assert json.loads(cli.stdout)["metrics"]["sum_of_costs"] == metrics["sum_of_costs"]
    broken = [list(p) for p in solution.plan]
    broken[0][1] = broken[0][0][0] + 5, broken[0][0][1]
    violation, _ = phalanx.validate(instance, broken)
    assert violation is not None and "agent 0" in violation


def test_replaying_a_plan_in_the_environment_gives_the_validators_figures(instance_file):
    instance = phalanx.read_instance(instance_file)
    plan = phalanx.solve(instance, "cbs").plan
    env = phalanx.parallel_env(instance=instance_file)
    env.reset()
    moves = {(0, 1): 0, (0, -1): 1, (-1, 0): 2, (1, 0): 3, (0, 0): 4}
    horizon = max(len(p) for p in plan)
    for t in range(1, horizon):
        actions = {}
        for i, path in enumerate(plan):
            (x0, y0), (x1, y1) = path[min(t - 1, len(path) - 1)], path[min(t, len(path) - 1)]
            actions[f"agent_{i}"] = moves[(x1 - x0, y1 - y0)]
        _, _, terminated, _, infos = env.step(actions)
    assert all(terminated.values())
    _, metrics = phalanx.validate(instance, env.world.trajectory())
    _, planned = phalanx.validate(instance, plan)
    assert metrics["makespan"] == planned["makespan"]
    assert metrics["formation_loss"] == pytest.approx(planned["formation_loss"])
    assert infos["agent_0"]["formation_loss"] == pytest.approx(0.0)


def play(policy, env):
    obs, _ = env.reset()
    policy.reset()
    while env.agents:
        obs, *_ = env.step(policy.act(obs))
    return env.world.trajectory()


@pytest.mark.parametrize("name", ["pathfinding", "hrl"])
def test_shipped_policy_in_python_plays_as_phalanx_solve(instance_file, name):
    policy = phalanx.load_policy(name)
    task = "meta" if name == "hrl" else name
    trajectory = play(policy, phalanx.parallel_env(instance=instance_file, task=task))
    solution = phalanx.solve(phalanx.read_instance(instance_file), name, rollouts=1)
    assert solution.plan is not None
    horizon = max(map(len, solution.plan))
    padded = [p + [p[-1]] * (horizon - len(p)) for p in solution.plan]
    assert trajectory == padded


def test_the_hierarchy_refuses_a_world_that_took_other_actions(instance_file):
    policy = phalanx.load_policy("hrl")
    env = phalanx.parallel_env(instance=instance_file, task="meta")
    obs, _ = env.reset()
    actions = policy.act(obs)
    env.step({a: (x + 1) % 4 for a, x in actions.items()})
    with pytest.raises(phalanx.PhalanxError, match="not where the hierarchy"):
        policy.act(env.step(actions)[0])
    with pytest.raises(phalanx.PhalanxError, match="observations of a phalanx environment"):
        policy.act({"agent_0": {}})


def test_render_modes():
    env = phalanx.parallel_env(size=16, render_mode="ansi", seed=2)
    env.reset()
    text = env.render()
    assert len(text.splitlines()) == 16 and "a" in text
    env = phalanx.parallel_env(size=16, render_mode="rgb_array", seed=2)
    env.reset()
    rgb = env.render()
    assert rgb.ndim == 3 and rgb.shape[2] == 3 and rgb.dtype == np.uint8
    env = phalanx.parallel_env(size=16, render_mode="svg", seed=2)
    env.reset()
    assert env.render().startswith("<svg")


def test_bad_input_raises_with_the_rust_message(tmp_path):
    with pytest.raises(phalanx.PhalanxError, match="task 'walk'|task \"walk\""):
        phalanx.parallel_env(task="walk")
    with pytest.raises(phalanx.PhalanxError, match="field of view 8"):
        phalanx.parallel_env(fov=8)
    with pytest.raises(ValueError, match="render_mode"):
        phalanx.parallel_env(render_mode="opengl")
    bad = tmp_path / "bad.yaml"
    bad.write_text("map:\n  dimensions: [4, 4]\n  obstacles: []\nagents:\n  - name: a\n    start: [9, 0]\n    goal: [1, 1]\n")
    with pytest.raises(phalanx.PhalanxError, match="bad.yaml"):
        phalanx.read_instance(bad)
    with pytest.raises(phalanx.PhalanxError, match="No such file"):
        phalanx.parallel_env(instance=tmp_path / "missing.yaml")
    env = phalanx.parallel_env(seed=1)
    with pytest.raises(phalanx.PhalanxError, match="reset first"):
        env.world.step([4, 4, 4])
    env.reset()
    with pytest.raises(phalanx.PhalanxError, match="action 7 is not one of 0..5"):
        env.step({"agent_0": 7})
    with pytest.raises(phalanx.PhalanxError, match="unknown agent"):
        env.step({"agent_9": 1})
    with pytest.raises(phalanx.PhalanxError, match="unknown method dijkstra"):
        phalanx.solve(phalanx.generate(), "dijkstra")
    with pytest.raises(phalanx.PhalanxError, match="not a positive number"):
        phalanx.solve(phalanx.generate(), "cbs", time_limit=-1)
    with pytest.raises(phalanx.PhalanxError, match="the plan has 1 paths"):
        phalanx.validate(phalanx.generate(), [[(0, 0)]])
    with pytest.raises(phalanx.PhalanxError, match="no weights"):
        phalanx.load_policy("pathfinding", weights=tmp_path)
    policy = phalanx.load_policy("pathfinding")
    obs, _ = env.reset()
    wrong = {a: dict(o, rank=np.array(0)) for a, o in obs.items()}
    with pytest.raises(phalanx.PhalanxError, match="not a permutation"):
        policy.act(wrong)


def test_copies_of_observations_are_plain_arrays_that_stay():
    import copy
    import pickle

    env = phalanx.parallel_env(seed=4)
    obs, _ = env.reset()
    kept = copy.deepcopy(obs["agent_0"])
    pickled = pickle.loads(pickle.dumps(obs["agent_0"]))
    assert type(kept) is dict and type(pickled) is dict
    before = np.copy(obs["agent_0"]["agents"])
    for _ in range(5):
        obs, *_ = env.step({a: 3 if a == "agent_0" else 4 for a in env.agents})
    assert not np.array_equal(obs["agent_0"]["agents"], before), "the team did not move"
    np.testing.assert_array_equal(kept["agents"], before)
    np.testing.assert_array_equal(pickled["agents"], before)
    assert kept["agents"] is not obs["agent_0"]["agents"]


def test_the_learned_solver_keeps_the_rollout_asked_for(instance_file, tmp_path):
    instance = phalanx.read_instance(instance_file)
    fastest = phalanx.solve(instance, "hrl", rollouts=4)
    tightest = phalanx.solve(instance, "hrl", rollouts=4, keep="tightest")
    assert fastest.solved and tightest.solved
    assert tightest.metrics["formation_loss"] <= fastest.metrics["formation_loss"]
    assert tightest.metrics["makespan"] >= fastest.metrics["makespan"]
    with pytest.raises(ValueError, match="keep \"best\": one of fastest, tightest, within"):
        phalanx.solve(instance, "hrl", keep="best")
    with pytest.raises(ValueError, match="not a number of at least 1"):
        phalanx.solve(instance, "hrl", keep="within:0.9")
    # The student keeps by its own rule unless told: the tightest within 1.1 x the lower
    # bound, its rollouts after the first sampled, as `phalanx solve` does.
    instance = phalanx.generate(seed=5)
    instance.write(tmp_path / "seed5.yaml")
    student = phalanx.solve(instance, "imitation", rollouts=4)
    cli = [phalanx_bin(), "solve", str(tmp_path / "seed5.yaml"), "--planner", "imitation"]
    cli += ["--rollouts", "4", "--json"]
    out = subprocess.run(cli, check=True, capture_output=True, text=True).stdout
    assert student.solved and json.loads(out)["metrics"] == student.metrics
    # On this instance the sampled rollouts are at least as fast as the fastest of greedy
    # ones with random actions, and tighter.
    before = "imitation:second=none+temp=none"
    fast = phalanx.solve(instance, before, rollouts=4, keep="fastest")
    assert student.metrics["makespan"] <= fast.metrics["makespan"]
    assert student.metrics["formation_loss"] < fast.metrics["formation_loss"]


def test_the_parallel_step_reads_actions_as_python_did():
    env = phalanx.parallel_env(seed=3)
    env.reset()
    # An agent left out waits; NumPy integers, floats and numeric strings go through int().
    obs, rewards, terminations, truncations, infos = env.step({"agent_1": np.int32(3)})
    assert set(rewards) == set(terminations) == set(truncations) == set(infos) == set(env.agents)
    assert all(type(r) is float for r in rewards.values())
    assert infos["agent_0"].keys() == {"formation_loss", "cancelled", "on_goal"}
    env.step({"agent_0": 2.0, "agent_2": "1"})
    assert env.world.t == 2
    for name in ("agent_3", "agent_01", "agent_-1", 0):
        with pytest.raises(phalanx.PhalanxError, match="unknown agent"):
            env.step({name: 1})
    with pytest.raises(phalanx.PhalanxError, match="agent 2: action -1 is not one of 0..5"):
        env.step({"agent_2": -1})
    assert env.world.t == 2


VECTOR = {"size": 10, "density": 0.15, "agents": 3}


def assert_rows_equal(vector_obs, row, single_obs, what):
    for agent, name in enumerate(sorted(single_obs, key=lambda n: int(n.split("_")[1]))):
        for key, value in single_obs[name].items():
            np.testing.assert_array_equal(
                vector_obs[key][row, agent], value, err_msg=f"{what} {key}"
            )


@pytest.mark.parametrize("task", ["pathfinding", "formation", "meta"])
def test_vector_env_plays_as_single_envs_seeded_by_the_documented_rule(task):
    num_envs, seed = 3, 21
    vec = phalanx.vector_env(num_envs, task=task, seed=seed, **VECTOR)
    singles = [
        phalanx.parallel_env(task=task, seed=seed + i * 2**32, **VECTOR) for i in range(num_envs)
    ]
    obs, infos = vec.reset()
    single_obs = [s.reset()[0] for s in singles]
    for i, single in enumerate(singles):
        assert_rows_equal(obs, i, single_obs[i], "reset")
        assert vec.world.instance(i).starts == single.world.instance.starts
        assert infos["formation_loss"][i] == single.world.formation_loss
        assert infos["on_goal"][i].tolist() == single.world.on_goal
    rng = np.random.default_rng(5)
    ended = 0
    seeds = [seed + i * 2**32 for i in range(num_envs)]
    for t in range(80):
        actions = rng.integers(0, 5, size=(num_envs, 3))
        obs, rewards, terminations, truncations, infos = vec.step(actions)
        for i, single in enumerate(singles):
            o, r, term, trunc, info = single.step(dict(zip(single.agents, actions[i].tolist())))
            names = list(r)
            np.testing.assert_array_equal(rewards[i], [r[n] for n in names])
            assert terminations[i].tolist() == [term[n] for n in names]
            assert truncations[i].tolist() == [trunc[n] for n in names]
            assert infos["cancelled"][i].tolist() == [info[n]["cancelled"] for n in names]
            assert infos["on_goal"][i].tolist() == [info[n]["on_goal"] for n in names]
            assert infos["formation_loss"][i] == info[names[0]]["formation_loss"]
            assert infos["_final_obs"][i] == (not single.agents)
            if not single.agents:
                ended += 1
                seeds[i] += 1
                assert_rows_equal(infos["final_obs"], i, o, f"step {t} final")
                o, _ = single.reset()
            assert_rows_equal(obs, i, o, f"step {t}")
            assert infos["seed"][i] == seeds[i]
    assert ended >= num_envs, "no episode ended: the auto-reset was not tested"


def test_vector_env_api_arrays_seeds_threads_and_bad_input():
    import gymnasium

    vec = phalanx.vector_env(4, num_threads=2, **VECTOR)
    assert isinstance(vec, gymnasium.vector.VectorEnv)
    assert vec.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.SAME_STEP
    with pytest.raises(phalanx.PhalanxError, match="reset first"):
        vec.step(np.zeros((4, 3), np.int64))
    obs, infos = vec.reset(seed=[7, 8, 9, 10])
    assert infos["seed"].tolist() == [7, 8, 9, 10]
    assert vec.observation_space.contains(obs) and obs["cost"].shape == (4, 3, 9, 9)
    single, _ = phalanx.parallel_env(seed=9, **VECTOR).reset()
    assert_rows_equal(obs, 2, single, "seed list")
    first = obs["agents"]
    out = vec.step(vec.action_space.sample().astype(np.int32))  # any integer dtype
    assert out[0]["agents"] is first and out[1].shape == (4, 3) and out[1].dtype == np.float32
    assert not np.shares_memory(out[0]["agents"], out[4]["final_obs"]["agents"])
    with pytest.raises(ValueError):
        out[1][0, 0] = 1.0
    # The same seed plays the same on one thread and on two.
    one = phalanx.vector_env(4, num_threads=1, seed=5, **VECTOR)
    two = phalanx.vector_env(4, num_threads=2, seed=5, **VECTOR)
    one.reset(), two.reset()
    rng = np.random.default_rng(1)
    for _ in range(40):
        actions = rng.integers(0, 5, size=(4, 3))
        a, b = one.step(actions), two.step(actions)
        for key in a[0]:
            np.testing.assert_array_equal(a[0][key], b[0][key])
        np.testing.assert_array_equal(a[1], b[1])
    # A reset without a seed goes on with each environment's next seed.
    seeds = one.step(np.full((4, 3), 4))[4]["seed"].copy()
    _, infos = one.reset()
    assert infos["seed"].tolist() == [s + 1 for s in seeds]
    with pytest.raises(phalanx.PhalanxError, match=r"actions of shape \[4, 2\]"):
        vec.step(np.zeros((4, 2), np.int64))
    with pytest.raises(phalanx.PhalanxError, match="env 1, agent 2: action 5 is not one of 0..5"):
        vec.step(np.array([[0, 0, 0], [0, 0, 5], [0, 0, 0], [9, 0, 0]]))
    with pytest.raises(phalanx.PhalanxError, match="dtype float64"):
        vec.step(np.zeros((4, 3)))
    with pytest.raises(phalanx.PhalanxError, match="3 seeds for 4 environments"):
        vec.reset(seed=[1, 2, 3])
    with pytest.raises(phalanx.PhalanxError, match="num_envs 0"):
        phalanx.vector_env(0)
    with pytest.raises(phalanx.PhalanxError, match="task"):
        phalanx.vector_env(2, task="walk")


def test_the_ppo_example_runs_on_the_vector():
    import sys

    script = ROOT / "examples" / "python" / "ppo_vector.py"
    out = subprocess.run(
        [sys.executable, str(script), "--iterations", "2", "--num-envs", "8", "--steps", "16",
         "--size", "10", "--minibatch", "128"],
        check=True, capture_output=True, text=True, timeout=120,
    )
    assert "iteration 2: team return" in out.stdout


STUDENT = """{"data": {"pool": {"n_maps": 3, "size": 16}, "agents": [3], "episodes": 4,
  "seed": 2, "expert": "swarm"}, "more_data": [], "batch_size": 2, "updates": 5, "rounds": 1,
  "round_episodes": 2, "round_updates": 4, "validation_maps": 1, "validation_max_side": 20,
  "finetune": null}"""


def read_plan_paths(path: pathlib.Path) -> list[list[tuple[int, int]]]:
    """The paths of a plan file in the block layout `phalanx` writes."""
    paths: list[list[tuple[int, int]]] = []
    in_schedule, x = False, None
    for line in path.read_text().splitlines():
        if line == "schedule:":
            in_schedule = True
        elif in_schedule and line.startswith("  ") and line[2] != " " and line.endswith(":"):
            paths.append([])
        elif in_schedule and line.startswith("    - x: "):
            x = int(line.split(":")[1])
        elif in_schedule and line.startswith("      y: "):
            paths[-1].append((x, int(line.split(":")[1])))
    return paths


def test_a_trained_imitation_student_plays_in_python_as_phalanx_solve(instance_file, tmp_path):
    config = tmp_path / "cfg.json"
    config.write_text(STUDENT)
    student = tmp_path / "student"
    train = ["train", "imitation", "--config", str(config), "--out", str(student)]
    subprocess.run([phalanx_bin(), *train], check=True, capture_output=True)
    policy = phalanx.load_policy("imitation", weights=student)
    assert policy.vector_len == 9
    # Loaded by its name, a student acts at the planners' student's test-time band, which
    # its environment takes.
    assert policy.team_deadband == 0.3
    # The student acts with its stall escape, as in `phalanx solve` (compared below).
    assert policy.escape == "4:0.5"
    policy.escape = "off"
    assert policy.escape is None
    with pytest.raises(phalanx.PhalanxError, match="VISITS:PROB"):
        policy.escape = "sometimes"
    policy.escape = "4:0.5"
    # Without the team vector the student names the environment it needs.
    place_only = phalanx.parallel_env(instance=instance_file, task="meta", place_vector=True)
    observations, _ = place_only.reset(seed=0)
    with pytest.raises(phalanx.PhalanxError, match="team_vector=True"):
        policy.act(observations)
    policy.reset()
    env = phalanx.parallel_env(
        instance=instance_file,
        task="meta",
        place_vector=True,
        team_vector=True,
        team_deadband=policy.team_deadband,
    )
    assert env.observation_space("agent_0")["place"].shape == (3,)
    assert env.observation_space("agent_0")["team"].shape == (3,)
    trajectory = play(policy, env)
    plan = tmp_path / "plan.yaml"
    solve = ["solve", str(instance_file), "--planner", "imitation", "--weights", str(student)]
    solve += ["--rollouts", "1", "--partial", "-o", str(plan)]
    assert subprocess.run([phalanx_bin(), *solve], capture_output=True).returncode in (0, 1)
    # The plan file trims each path's trailing waits: both are compared padded with them.
    played = [[tuple(c) for c in p] for p in trajectory]
    paths = read_plan_paths(plan)
    horizon = max(map(len, paths + played))
    pad = lambda ps: [p + [p[-1]] * (horizon - len(p)) for p in ps]  # noqa: E731
    assert pad(played) == pad(paths)


def test_the_team_vectors_dead_band_is_an_environment_setting():
    settings = dict(size=16, agents=3, task="meta", place_vector=True, team_vector=True)
    assert phalanx.TEAM_DEADBAND == 1.5
    with pytest.raises(phalanx.PhalanxError, match="dead band -1"):
        phalanx.parallel_env(team_deadband=-1, **settings)
    # The same random walk seen with no band and with a band no lag reaches: the second
    # shows the agent in front only zeros, the first does not once the team is out of shape.
    seen = {}
    for band in (0.0, 1e9):
        env = phalanx.parallel_env(team_deadband=band, seed=3, **settings)
        observations, _ = env.reset(seed=3)
        rng = np.random.default_rng(0)
        teams = []
        for _ in range(20):
            teams += [obs["team"].copy() for obs in observations.values()]
            actions = {a: int(rng.integers(0, 5)) for a in env.agents}
            observations, *_ = env.step(actions)
            if not env.agents:
                break
        seen[band] = np.array(teams)
    assert seen[1e9].shape == seen[0.0].shape
    assert not seen[1e9].any() and seen[0.0].any()


def test_vector_env_is_the_same_on_any_thread_count_with_uneven_blocks():
    # 13 environments cut into blocks of two and one (three threads: the caller from the
    # front, two helpers from the back), the global pool's count, and one thread: the same
    # arrays, the ended episodes' last observations and the seeds included.
    vecs = [phalanx.vector_env(13, num_threads=t, seed=8, **VECTOR) for t in (1, 3, None)]
    for vec in vecs:
        vec.reset()
    rng = np.random.default_rng(2)
    ended = 0
    for _ in range(60):
        actions = rng.integers(0, 5, size=(13, 3))
        outs = [vec.step(actions) for vec in vecs]
        obs, rewards, terminations, truncations, infos = outs[0]
        ended += int(infos["_final_obs"].sum())
        for other in outs[1:]:
            for key in obs:
                np.testing.assert_array_equal(obs[key], other[0][key], err_msg=key)
            np.testing.assert_array_equal(rewards, other[1])
            np.testing.assert_array_equal(terminations, other[2])
            np.testing.assert_array_equal(truncations, other[3])
            np.testing.assert_array_equal(infos["seed"], other[4]["seed"])
            np.testing.assert_array_equal(infos["_final_obs"], other[4]["_final_obs"])
            rows = infos["_final_obs"]
            for key in infos["final_obs"]:
                np.testing.assert_array_equal(
                    infos["final_obs"][key][rows], other[4]["final_obs"][key][rows], err_msg=key
                )
    assert ended > 0, "no episode ended: the auto-reset was not compared"
