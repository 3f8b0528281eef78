//! An agent deciding alone (its own recurrent state, its observation, the actions of the
//! agents before it) chooses, step after step, what the batched policy chooses for it, with
//! its recurrent pass and its head in one call or apart.

use phalanx_env::{EnvConfig, MarlEnv, ObsBuffers, PoolConfig, PoolEnv, Task};
use phalanx_rl::{AgentError, AgentPolicy, Escape};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

#[test]
fn agents_deciding_alone_act_as_the_batched_policy() {
    let (policy, _) = phalanx_rl::models::load(None, "pathfinding").expect("the shipped policy");
    let pool = PoolConfig { n_maps: 3, ..PoolConfig::default() };
    for (n_agents, seed) in [(3, 1), (5, 2)] {
        let mut env =
            PoolEnv::new(Task::PathFinding, &pool, EnvConfig::default(), n_agents).unwrap();
        let mut obs = ObsBuffers::new(n_agents, env.obs_shape());
        env.reset(seed, &mut obs);
        let mut team = policy.clone();
        team.reset();
        let mut agents: Vec<AgentPolicy> =
            (0..n_agents).map(|a| AgentPolicy::new(policy.clone(), a).unwrap()).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let mut batched = vec![0_u8; n_agents];
        let mut alone = vec![0_u8; n_agents];
        let mut steps = 0;
        for step in 0..60 {
            steps += 1;
            team.act(&obs, 0.0, &mut rng, &mut batched);
            // Every agent's recurrent pass first, then the heads in order (as the hierarchy's
            // agents will), for odd steps; `act` for even ones.
            let features: Vec<_> = (0..n_agents)
                .map(|a| (step % 2 == 1).then(|| agents[a].observe(obs.grid_of(a), obs.vec_of(a))))
                .collect();
            let mut earlier = Vec::new();
            for &agent in &obs.order {
                let mask = obs.mask_of(agent);
                let action = match &features[agent] {
                    Some(features) => {
                        agents[agent].choose(features.as_ref().unwrap(), mask, &earlier)
                    }
                    None => {
                        agents[agent].act(obs.grid_of(agent), obs.vec_of(agent), mask, &earlier)
                    }
                }
                .unwrap();
                alone[agent] = action;
                earlier.push((agent, action));
            }
            assert_eq!(alone, batched, "{n_agents} agents, step {step}");
            let out = env.step(&batched, &mut obs);
            if out.terminated || out.truncated {
                break;
            }
        }
        assert!(steps >= 20, "{n_agents} agents: the episode ran {steps} steps only");
    }
}

#[test]
fn agents_deciding_alone_escape_stalls_as_the_batched_policy() {
    let (mut policy, _) = phalanx_rl::models::load(None, "pathfinding").unwrap();
    let greedy = policy.clone();
    // Every step off the goal counts as a stall: the escape acts often.
    policy.set_escape(Some(Escape { visits: 1, prob: 0.3 }));
    let pool = PoolConfig { n_maps: 3, ..PoolConfig::default() };
    let n_agents = 4;
    let mut env = PoolEnv::new(Task::PathFinding, &pool, EnvConfig::default(), n_agents).unwrap();
    let mut obs = ObsBuffers::new(n_agents, env.obs_shape());
    let (mut escaped, mut steps) = (0, 0);
    for seed in 0..3 {
        env.reset(seed, &mut obs);
        let (mut team, mut plain) = (policy.clone(), greedy.clone());
        team.reset();
        plain.reset();
        let mut agents: Vec<AgentPolicy> =
            (0..n_agents).map(|a| AgentPolicy::new(policy.clone(), a).unwrap()).collect();
        let mut rng = ChaCha8Rng::seed_from_u64(0);
        let (mut batched, mut alone, mut base) =
            (vec![0_u8; n_agents], vec![0; n_agents], vec![0; n_agents]);
        for step in 0..96 {
            team.act(&obs, 0.0, &mut rng, &mut batched);
            plain.act(&obs, 0.0, &mut rng, &mut base);
            let mut earlier = Vec::new();
            for &agent in &obs.order {
                let mask = obs.mask_of(agent);
                let action =
                    agents[agent].act(obs.grid_of(agent), obs.vec_of(agent), mask, &earlier);
                alone[agent] = action.unwrap();
                earlier.push((agent, alone[agent]));
            }
            assert_eq!(alone, batched, "episode {seed}, step {step}");
            escaped += usize::from(batched != base);
            steps += 1;
            let out = env.step(&batched, &mut obs);
            if out.terminated || out.truncated {
                break;
            }
        }
    }
    assert!(escaped >= 20, "the escape changed {escaped} of {steps} steps");
}

#[test]
fn an_agent_refuses_inputs_that_do_not_fit() {
    let (policy, _) = phalanx_rl::models::load(None, "pathfinding").unwrap();
    assert!(matches!(AgentPolicy::new(policy.clone(), 99), Err(AgentError::Slot { .. })));
    let mut agent = AgentPolicy::new(policy, 0).unwrap();
    let (grid, vector) = (vec![0.0; 4 * 81], vec![0.0; 3]);
    let mask = [true; 5];
    assert!(matches!(
        agent.act(&grid[1..], &vector, &mask, &[]),
        Err(AgentError::Size { what: "grid", .. })
    ));
    assert_eq!(agent.act(&grid, &vector, &[false; 5], &[]), Err(AgentError::NoAction));
    assert_eq!(
        agent.act(&grid, &vector, &mask, &[(1, 9)]),
        Err(AgentError::Message { agent: 1, action: 9 })
    );
    assert!(agent.act(&grid, &vector, &mask, &[(1, 2)]).is_ok());
    let features = agent.observe(&grid, &vector).unwrap();
    assert!(matches!(
        agent.observe(&grid, &vector[1..]),
        Err(AgentError::Size { what: "vector", .. })
    ));
    assert!(matches!(
        agent.choose(&features, &mask[1..], &[]),
        Err(AgentError::Size { what: "mask", .. })
    ));
    assert_eq!(
        agent.choose(&features, &mask, &[(8, 0)]),
        Err(AgentError::Message { agent: 8, action: 0 })
    );
}
