//! Decentralised runs as processes over Zenoh (docs/runtime.md): `phalanx world` and one
//! `phalanx agent` per agent give the plan of `phalanx solve --planner pathfinding --rollouts
//! 1` (with `--policy hrl` that of `--planner hrl`, with `--policy imitation` that of
//! `--planner imitation`, its stall escape included), on loopback and across two network
//! namespaces joined by a veth pair; an agent killed mid-episode waits while the others go on
//! and rejoins when restarted; agents stop with exit code 6 when the world is killed, for
//! either policy. Every wait is bounded.

use std::io::{BufRead as _, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use crate::{check, phalanx};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_phalanx"))
}

/// A TCP port free on loopback now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The plan `file` in `dir` for the instance `inst.yaml` there.
fn plan(dir: &Path, file: &str) -> phalanx_core::Plan {
    let names = phalanx_io::read_instance(&dir.join("inst.yaml"), None).unwrap().names;
    phalanx_io::read_plan_for(&dir.join(file), &names).unwrap()
}

/// Generates `inst.yaml` (side `size`, `agents` agents, seed `seed`) and the plan of one
/// greedy rollout of the learned solver `planner`, `solve.yaml`.
fn instance_and_solve(dir: &Path, size: &str, agents: &str, seed: &str, planner: &str) {
    let args = ["gen", "--size", size, "--agents", agents, "--seed", seed, "-o", "inst.yaml"];
    check(&phalanx(dir, &args), 0);
    let solve = ["solve", "inst.yaml", "--planner", planner, "--rollouts", "1"];
    check(&phalanx(dir, &[&solve[..], &["-o", "solve.yaml"]].concat()), 0);
}

/// Kills the children left when dropped (a failed assertion leaves no process behind).
struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Waits at most `limit` for `child`; its exit code.
fn wait_for(child: &mut Child, limit: Duration) -> Option<i32> {
    let deadline = Instant::now() + limit;
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        assert!(Instant::now() < deadline, "a process ran past {limit:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The lines a child writes to stderr, as they come.
fn stderr_lines(child: &mut Child) -> Receiver<String> {
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    rx
}

/// Waits at most 60 s for the world's line saying the episode starts.
fn await_start(lines: &Receiver<String>) {
    loop {
        let line = lines.recv_timeout(Duration::from_secs(60)).expect("the episode starts");
        if line.contains("the episode starts") {
            return;
        }
    }
}

fn agent(dir: &Path, id: usize, endpoint: &str, prefix: &str, policy: &str) -> Child {
    bin()
        .args(["agent", "--id", &id.to_string(), "--connect", endpoint, "--prefix", prefix])
        .args(["--policy", policy])
        .current_dir(dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

#[test]
fn processes_over_zenoh_plan_what_the_batched_policy_plans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    instance_and_solve(d, "20", "4", "5", "pathfinding");
    let args = ["run", "inst.yaml", "--processes", "-o", "proc.yaml", "--json"];
    let (json, _) = check(&phalanx(d, &args), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["outcome"], "solved", "{json}");
    assert_eq!((v["missed_actions"].as_u64(), v["stale_actions"].as_u64()), (Some(0), Some(0)));
    assert_eq!(plan(d, "proc.yaml"), plan(d, "solve.yaml"));

    // Bad input names the value and exits 2; a world nobody joins gives up (exit 6).
    let (_, stderr) = check(&phalanx(d, &["agent", "--id", "0", "--connect", "nowhere"]), 2);
    assert!(stderr.contains("nowhere"), "{stderr}");
    let (_, stderr) = check(&phalanx(d, &["world", "inst.yaml", "--listen", "tcp/x:y"]), 2);
    assert!(stderr.contains("tcp/x:y"), "{stderr}");
    let port = free_port().to_string();
    let args = ["world", "inst.yaml", "--listen", &format!("tcp/127.0.0.1:{port}")];
    let (_, stderr) = check(&phalanx(d, &[&args[..], &["--join-timeout", "0.5"]].concat()), 6);
    assert!(stderr.contains("not ready: [0, 1, 2, 3]"), "{stderr}");
}

#[test]
fn processes_over_zenoh_plan_what_the_batched_hierarchy_plans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    instance_and_solve(d, "20", "3", "3", "hrl");
    let args = ["run", "inst.yaml", "--processes", "--policy", "hrl", "-o", "proc.yaml", "--json"];
    let (json, _) = check(&phalanx(d, &args), 0);
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        (v["outcome"].as_str(), v["planner"].as_str()),
        (Some("solved"), Some("hrl (decentralised)")),
        "{json}"
    );
    let missed = ["missed_actions", "missed_choices", "stale_actions"].map(|k| v[k].as_u64());
    assert_eq!(missed, [Some(0); 3], "{json}");
    assert_eq!(plan(d, "proc.yaml"), plan(d, "solve.yaml"));
}

#[test]
fn processes_over_zenoh_plan_what_the_batched_imitation_student_plans() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("cfg.json"), crate::imitation::CONFIG).unwrap();
    let train = ["train", "imitation", "--config", "cfg.json", "--out", "student"];
    check(&phalanx(d, &train), 0);
    let args = ["gen", "--size", "20", "--agents", "3", "--seed", "3", "-o", "inst.yaml"];
    check(&phalanx(d, &args), 0);
    // A student of a few updates rarely reaches the goals: the trajectories are compared
    // whole, wherever they end (--partial).
    let solve = ["solve", "inst.yaml", "--planner", "imitation", "--weights", "student"];
    let solved =
        phalanx(d, &[&solve[..], &["--rollouts", "1", "--partial", "-o", "solve.yaml"]].concat());
    let code = solved.status.code();
    assert!(matches!(code, Some(0 | 1)), "{solved:?}");
    let args = ["run", "inst.yaml", "--processes", "--policy", "imitation", "--weights", "student"];
    let ran = phalanx(d, &[&args[..], &["--partial", "-o", "proc.yaml", "--json"]].concat());
    let (json, _) = check(&ran, code.unwrap());
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v["planner"].as_str(), Some("imitation (decentralised)"), "{json}");
    let missed = ["missed_actions", "stale_actions"].map(|k| v[k].as_u64());
    assert_eq!(missed, [Some(0); 2], "{json}");
    assert_eq!(plan(d, "proc.yaml"), plan(d, "solve.yaml"));
    // The student's stall escape acted in both (its draws are each agent's own): without it
    // the batched student plans otherwise.
    let greedy = ["--rollouts", "1", "--partial", "--escape", "off", "-o", "greedy.yaml"];
    phalanx(d, &[&solve[..], &greedy[..]].concat());
    assert_ne!(plan(d, "greedy.yaml"), plan(d, "solve.yaml"));
}

#[test]
fn the_shipped_student_runs_decentralised_with_its_dead_band() {
    // The shipped student acts at its test-time band (0.3); the world writes the team
    // vector with it, in this process and as a process of its own. On this instance the
    // default band of 1.5 plays another plan.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    instance_and_solve(d, "20", "3", "4", "imitation");
    let default = ["solve", "inst.yaml", "--planner", "imitation", "--rollouts", "1"];
    let wide = ["--team-deadband", "1.5", "-o", "wide.yaml"];
    check(&phalanx(d, &[&default[..], &wide[..]].concat()), 0);
    assert_ne!(plan(d, "wide.yaml"), plan(d, "solve.yaml"));
    for (how, file) in [(&[][..], "run.yaml"), (&["--processes"][..], "proc.yaml")] {
        let args = ["run", "inst.yaml", "--policy", "imitation", "-o", file];
        check(&phalanx(d, &[&args[..], how].concat()), 0);
        assert_eq!(plan(d, file), plan(d, "solve.yaml"), "phalanx run {how:?}");
    }
}

#[test]
fn a_killed_agent_waits_and_rejoins_and_a_killed_world_stops_the_agents() {
    killed_agent_and_world("pathfinding");
}

#[test]
fn a_killed_agent_of_the_hierarchy_waits_and_rejoins_and_a_killed_world_stops_the_agents() {
    killed_agent_and_world("hrl");
}

/// Agent 1 of a team of `policy` killed mid-episode and restarted, then the world killed.
fn killed_agent_and_world(policy: &str) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["gen", "--size", "32", "--agents", "3", "--seed", "2", "-o", "inst.yaml"];
    check(&phalanx(d, &args), 0);
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let prefix = format!("phalanx-test/kill/{}", std::process::id());
    // The world at 50 ms a step and agents 0, 1, 2 (processes 1, 2, 3), once it started.
    let team = || {
        let args = ["world", "inst.yaml", "--listen", &endpoint, "--prefix", &prefix, "--json"];
        let world = bin()
            .args(args)
            .args(["--policy", policy])
            .args(["--step-period", "50", "--step-timeout", "300"])
            .current_dir(d)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut procs = Children(vec![world]);
        let lines = stderr_lines(&mut procs.0[0]);
        for id in 0..3 {
            procs.0.push(agent(d, id, &endpoint, &prefix, policy));
        }
        await_start(&lines);
        procs
    };

    // Agent 1 is killed ten steps in and restarted ten steps later.
    let mut procs = team();
    std::thread::sleep(Duration::from_millis(500));
    procs.0[2].kill().unwrap();
    procs.0[2].wait().unwrap();
    std::thread::sleep(Duration::from_millis(500));
    procs.0.push(agent(d, 1, &endpoint, &prefix, policy));
    let code = wait_for(&mut procs.0[0], Duration::from_secs(120));
    let mut out = String::new();
    std::io::Read::read_to_string(procs.0[0].stdout.as_mut().unwrap(), &mut out).unwrap();
    assert!(matches!(code, Some(0 | 1)), "{code:?} {out}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let missed: Vec<u64> =
        v["missed_by_agent"].as_array().unwrap().iter().map(|m| m.as_u64().unwrap()).collect();
    // The makespan when solved, else the step limit (3 × 32).
    let steps = v["metrics"]["makespan"].as_u64().unwrap_or(96);
    assert_eq!((missed[0], missed[2]), (0, 0), "{out}");
    assert!(missed[1] >= 3, "agent 1 missed the steps it was away: {out}");
    assert!(missed[1] + 5 < steps, "agent 1 acted again after its restart ({steps} steps): {out}");
    if policy == "hrl" {
        let choices: Vec<u64> = v["missed_choices_by_agent"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_u64().unwrap())
            .collect();
        assert_eq!((choices[0], choices[2]), (0, 0), "{out}");
        assert!(choices[1] >= 3 && choices[1] + 5 < steps, "agent 1 chose again: {out}");
    }
    for i in [1, 3, 4] {
        assert_eq!(
            wait_for(&mut procs.0[i], Duration::from_secs(20)),
            Some(0),
            "agent process {i}"
        );
    }

    // The world is killed mid-episode: every agent stops with code 6, saying so.
    let mut procs = team();
    std::thread::sleep(Duration::from_millis(300));
    procs.0[0].kill().unwrap();
    let killed = Instant::now();
    for i in 1..4 {
        assert_eq!(wait_for(&mut procs.0[i], Duration::from_secs(20)), Some(6), "agent {i}");
        let mut err = String::new();
        std::io::Read::read_to_string(procs.0[i].stderr.as_mut().unwrap(), &mut err).unwrap();
        assert!(err.contains("world"), "{err}");
    }
    assert!(killed.elapsed() < Duration::from_secs(20));
}

/// Two network namespaces joined by a veth pair: the world's host and the agents' host.
struct Hosts {
    names: [String; 2],
}

impl Hosts {
    /// `None` when namespaces cannot be made here (not root, no `ip`).
    fn new() -> Option<Hosts> {
        let id = std::process::id();
        let names = [format!("phxw{id}"), format!("phxa{id}")];
        let subnet = format!("10.231.{}", id % 250);
        let ip = |args: &[&str]| {
            Command::new("ip").args(args).stderr(Stdio::null()).status().is_ok_and(|s| s.success())
        };
        if !ip(&["netns", "add", &names[0]]) {
            return None;
        }
        let hosts = Hosts { names };
        let [w, a] = &hosts.names;
        let (vw, va) = (format!("vw{id}"), format!("va{id}"));
        let ok = ip(&["netns", "add", a])
            && ip(&["link", "add", &vw, "type", "veth", "peer", "name", &va])
            && ip(&["link", "set", &vw, "netns", w])
            && ip(&["link", "set", &va, "netns", a])
            && ip(&["-n", w, "addr", "add", &format!("{subnet}.1/30"), "dev", &vw])
            && ip(&["-n", a, "addr", "add", &format!("{subnet}.2/30"), "dev", &va])
            && [(w, &vw), (a, &va)].iter().all(|(ns, dev)| {
                ip(&["-n", ns, "link", "set", dev, "up"])
                    && ip(&["-n", ns, "link", "set", "lo", "up"])
            });
        assert!(ok, "setting up the namespaces and the veth pair");
        Some(hosts)
    }

    fn subnet() -> String {
        format!("10.231.{}", std::process::id() % 250)
    }

    /// Bytes sent by the world's end of the veth pair, and by the agents' end.
    fn bytes_sent(&self) -> (u64, u64) {
        let id = std::process::id();
        let read = |ns: &str, dev: String| {
            let out = Command::new("ip")
                .args([
                    "netns",
                    "exec",
                    ns,
                    "cat",
                    &format!("/sys/class/net/{dev}/statistics/tx_bytes"),
                ])
                .output()
                .unwrap();
            String::from_utf8_lossy(&out.stdout).trim().parse::<u64>().unwrap()
        };
        (read(&self.names[0], format!("vw{id}")), read(&self.names[1], format!("va{id}")))
    }

    fn exec(&self, host: usize) -> Command {
        let mut command = Command::new("ip");
        command.args(["netns", "exec", &self.names[host], env!("CARGO_BIN_EXE_phalanx")]);
        command
    }
}

impl Drop for Hosts {
    fn drop(&mut self) {
        for name in &self.names {
            let _ = Command::new("ip").args(["netns", "del", name]).stderr(Stdio::null()).status();
        }
    }
}

#[test]
#[allow(
    clippy::print_stderr,
    reason = "it reports the bytes that crossed the veth pair, or why it was skipped"
)]
fn world_and_agents_on_two_hosts_plan_what_the_batched_policy_plans() {
    let Some(hosts) = Hosts::new() else {
        // CI sets PHALANX_NETNS_CHECK=1 where namespaces can be made: there the test must run.
        assert!(
            std::env::var_os("PHALANX_NETNS_CHECK").is_none(),
            "network namespaces cannot be made (ip netns add failed)"
        );
        eprintln!("skipped: network namespaces cannot be made here (not root, or no `ip`)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    instance_and_solve(d, "20", "3", "7", "pathfinding");
    let world_ip = format!("{}.1", Hosts::subnet());
    let agents_ip = format!("{}.2", Hosts::subnet());
    let endpoint = format!("tcp/{world_ip}:7447");
    let before = hosts.bytes_sent();
    let world = hosts
        .exec(0)
        .args(["world", "inst.yaml", "--listen", &endpoint, "--json", "-o", "net.yaml"])
        .current_dir(d)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut procs = Children(vec![world]);
    for id in 0..3 {
        let listen = format!("tcp/{agents_ip}:0");
        let agent = hosts
            .exec(1)
            .args(["agent", "--id", &id.to_string(), "--connect", &endpoint, "--listen", &listen])
            .current_dir(d)
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        procs.0.push(agent);
    }
    assert_eq!(wait_for(&mut procs.0[0], Duration::from_secs(120)), Some(0));
    for i in 1..4 {
        assert_eq!(wait_for(&mut procs.0[i], Duration::from_secs(20)), Some(0), "agent {i}");
    }
    let after = hosts.bytes_sent();
    assert_eq!(plan(d, "net.yaml"), plan(d, "solve.yaml"));
    let steps = plan(d, "net.yaml").n_steps() as u64 - 1;
    let (world_bytes, agent_bytes) = (after.0 - before.0, after.1 - before.1);
    assert!(world_bytes > 0 && agent_bytes > 0, "the messages crossed the veth pair");
    eprintln!(
        "two hosts: {steps} steps, world sent {world_bytes} B ({} B per agent and step), the \
         agents' host {agent_bytes} B",
        world_bytes / (3 * steps.max(1))
    );
}

#[test]
fn an_agent_outside_the_team_or_with_an_unreachable_world_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("i.yaml"), crate::INSTANCE).unwrap();
    let endpoint = format!("tcp/127.0.0.1:{}", free_port());
    let prefix = format!("hostile{}", free_port());
    let world = bin()
        .args(["world", "i.yaml", "--listen", &endpoint, "--prefix", &prefix])
        .args(["--join-timeout", "60"])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let _world = Children(vec![world]);
    let started = Instant::now();
    let args = ["agent", "--id", "5", "--connect", &endpoint, "--prefix", &prefix];
    let (_, stderr) = check(&phalanx(d, &[&args[..], &["--join-timeout", "30"]].concat()), 2);
    assert!(stderr.contains("agent 5: the world's team has 2 agents (ids 0 to 1)"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(20), "not the join timeout");

    for address in ["tcp/999.1.1.1:1", "tcp/127.0.0.1:99999", "tcp/127.0.0.1"] {
        let (_, stderr) = check(&phalanx(d, &["agent", "--id", "0", "--connect", address]), 2);
        assert!(stderr.contains(address) && stderr.contains("--connect"), "{stderr}");
    }
}
