//! Imitation data: the expert's episodes are valid plans, the labels' messages are what the
//! environment shows at test time, the file round-trips and refuses damage, and the data
//! is the same on one thread or two.

use phalanx_core::validate;

use super::*;

/// A small data set's settings: a few 16² pool maps, short episodes, the fast expert.
fn small(noise: f64, episodes: u64) -> DataConfig {
    DataConfig {
        pool: PoolConfig { n_maps: 3, size: 16, ..PoolConfig::default() },
        agents: vec![3, 4],
        episodes,
        seed: 5,
        noise,
        expert: ExpertChoice::Swarm,
        ..DataConfig::default()
    }
}

fn data(noise: f64, episodes: u64) -> Dataset {
    generate(&small(noise, episodes), &|_| {}).unwrap().0
}

#[test]
fn expert_episodes_without_noise_are_valid_plans_to_the_goals() {
    let swarm = data(0.0, 4);
    let default_expert = DataConfig { expert: DataConfig::default().expert, ..small(0.0, 2) };
    let swarm_jsa = generate(&default_expert, &|_| {}).unwrap().0;
    for episode in swarm.episodes.iter().chain(&swarm_jsa.episodes) {
        assert_eq!(episode.end, EpisodeEnd::Reached);
        assert_eq!(episode.replans, 1, "on its own plan the expert plans once");
        let plan = episode.plan();
        validate(&episode.instance, &plan).unwrap();
        assert!(episode.steps.iter().all(|s| s.expert == s.taken));
    }
}

#[test]
fn noisy_episodes_leave_the_plan_and_the_expert_re_plans() {
    let data = generate(&small(0.2, 4), &|_| {}).unwrap().0;
    let replans: u32 = data.episodes.iter().map(|e| e.replans).sum();
    assert!(replans > 4, "{replans} re-plans");
    for episode in &data.episodes {
        // The taken moves are the environment's: the positions form a valid plan prefix
        // whenever the episode reached the goals.
        if episode.end == EpisodeEnd::Reached {
            validate(&episode.instance, &episode.plan()).unwrap();
        }
    }
}

#[test]
fn a_student_that_stands_still_ends_its_rollout_as_stalled() {
    let config = small(0.0, 1);
    let pool = TrainPool::new(&config.pool).unwrap();
    let instance = pool.sample_episode(3, 0.0, &mut episode_rng(1, 0));
    let expert = config.expert.config(config.node_limit);
    let mut env = Env::new(config.env.clone()).unwrap();
    // Standing still: the start is reached a third time before the third step.
    let mut wait = |_: &Env, _: &[u16], _: &[Action], taken: &mut [Action]| {
        taken.fill(Action::Wait);
    };
    let rule = LeaderRule::PathFinding;
    let (episode, _) = rollout_with(&mut env, &instance, &expert, rule, 3, &mut wait).unwrap();
    assert_eq!((episode.end, episode.steps.len()), (EpisodeEnd::Stalled, 2));
    // Without the cut the same student stands until the step limit.
    let (episode, _) = rollout_with(&mut env, &instance, &expert, rule, 0, &mut wait).unwrap();
    assert_eq!(episode.end, EpisodeEnd::Truncated);
}

#[test]
fn messages_are_the_expert_actions_of_the_agents_ranked_before() {
    let config = small(0.1, 3);
    let data = generate(&config, &|_| {}).unwrap().0;
    for episode in &data.episodes {
        // Test time: the environment's own message after the earlier ranks chose.
        let mut env = Env::new(config.env.clone()).unwrap();
        env.reset(&episode.instance).unwrap();
        let n = episode.instance.n_agents();
        let mut expected: Vec<Vec<f32>> = Vec::new();
        for step in &episode.steps {
            env.begin_turns(config.leader_rule);
            let mut row = vec![0.0f32; n * N_ACTIONS];
            while let Some(agent) = env.current_agent() {
                env.write_message(agent, &mut row);
                expected.push(row.clone());
                env.choose(step.expert[agent]);
            }
            env.step(&step.taken);
        }
        let mut k = 0;
        let mut replay = Env::new(config.env.clone()).unwrap();
        replay.reset(&episode.instance).unwrap();
        let mut at = 0;
        for_each_sample(episode, &config.env, config.leader_rule, |s| {
            while at < s.t {
                replay.step(&episode.steps[at].taken);
                at += 1;
            }
            assert_eq!(s.message, expected[k].as_slice(), "sample {k}");
            let step = &episode.steps[s.t];
            assert_eq!(usize::from(step.order[s.rank]), s.agent);
            assert_eq!(s.target, step.expert[s.agent]);
            assert!(s.mask[s.target.index()], "the label is allowed by the mask");
            assert_eq!(s.grid.len(), 4 * 9 * 9);
            // The goal vector, then the place vector on the agent in front, then the team
            // vector, the front agent's only.
            assert_eq!(s.vector.len(), 9);
            let front = usize::from(step.order[0]);
            let mut place = [0.0; 3];
            replay.write_place_vector(s.agent, front, &mut place);
            assert_eq!(&s.vector[3..6], place, "sample {k}");
            let mut team = [0.0; 3];
            if s.agent == front {
                replay.write_team_vector(s.agent, replay.team_shift(), &mut team);
            }
            assert_eq!(&s.vector[6..], team, "sample {k}");
            k += 1;
        })
        .unwrap();
        assert_eq!(k as u64, episode.n_samples());
    }
}

#[test]
fn the_file_round_trips() {
    let data = data(0.1, 5);
    let bytes = data.to_bytes();
    let back = Dataset::from_bytes(&bytes).unwrap();
    assert_eq!(back, data);
    assert_eq!(back.to_bytes(), bytes);
}

#[test]
fn a_damaged_file_is_refused_with_the_place_named() {
    let data = data(0.0, 3);
    let bytes = data.to_bytes();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let first_episode = 16 + json_len + 4;

    let mut flipped = bytes.clone();
    flipped[first_episode + 40] ^= 0x10;
    let err = Dataset::from_bytes(&flipped).unwrap_err();
    assert!(matches!(err, DataError::Checksum { .. }), "{err}");
    assert!(err.to_string().contains("episode 0"), "{err}");

    let mut header = bytes.clone();
    header[20] ^= 1;
    let err = Dataset::from_bytes(&header).unwrap_err();
    assert!(err.to_string().contains("header"), "{err}");

    let err = Dataset::from_bytes(&bytes[..bytes.len() - 3]).unwrap_err();
    assert!(matches!(err, DataError::Truncated { .. }), "{err}");
    assert!(err.to_string().contains("episode 2"), "{err}");

    let err = Dataset::from_bytes(&bytes[..first_episode]).unwrap_err();
    assert!(matches!(err, DataError::Counts { what: "episodes", .. }), "{err}");

    let mut longer = bytes.clone();
    longer.push(0);
    assert!(matches!(Dataset::from_bytes(&longer).unwrap_err(), DataError::Trailing(1)));

    let mut version = bytes.clone();
    version[8] = 9;
    assert!(matches!(Dataset::from_bytes(&version).unwrap_err(), DataError::Version(9)));
    assert!(matches!(Dataset::from_bytes(b"not a data file").unwrap_err(), DataError::Magic));
    assert!(matches!(Dataset::from_bytes(b"PHX").unwrap_err(), DataError::Truncated { .. }));
}

#[test]
fn a_body_with_a_valid_checksum_but_bad_values_is_refused() {
    let data = data(0.0, 1);
    let bytes = data.to_bytes();
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let body_at = 16 + json_len + 4 + 4;
    let body_len = u32::from_le_bytes(bytes[body_at - 4..body_at].try_into().unwrap()) as usize;
    let mut damaged = bytes.clone();
    // The end code (after index u64, agents u16, width u32, height u32).
    damaged[body_at + 18] = 7;
    let crc = crc32fast::hash(&damaged[body_at..body_at + body_len]);
    damaged[body_at + body_len..body_at + body_len + 4].copy_from_slice(&crc.to_le_bytes());
    let err = Dataset::from_bytes(&damaged).unwrap_err();
    assert!(err.to_string().contains("end code 7"), "{err}");
}

#[test]
fn the_same_seed_gives_the_same_file_on_one_or_two_threads() {
    let config = small(0.1, 6);
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| generate(&config, &|_| {}).unwrap().0.to_bytes())
    };
    assert_eq!(on(1), on(2));
}

#[test]
fn settings_out_of_range_are_refused_by_name() {
    let bad = |config: DataConfig, field: &str| {
        let err = generate(&config, &|_| {}).unwrap_err();
        assert!(err.to_string().contains(field), "{err}");
    };
    bad(DataConfig { agents: vec![], ..small(0.0, 1) }, "agents");
    bad(DataConfig { agents: vec![3, 99], ..small(0.0, 1) }, "agents");
    bad(DataConfig { noise: 1.5, ..small(0.0, 1) }, "noise");
}

#[test]
fn data_of_other_observations_holds_the_same_expert_episodes() {
    // The expert's episodes do not depend on what the observations hold: data made without
    // the place vector is the data of a run with the place and team vectors, sample for
    // sample but for the vectors the replay now writes.
    let team = small(0.1, 2);
    assert!(team.env.place_vector && team.env.team_vector);
    let env = EnvConfig { place_vector: false, team_vector: false, ..team.env.clone() };
    let bare = DataConfig { env, ..team.clone() };
    assert!(bare.same_episodes(&team) && team.same_episodes(&bare));
    let narrow =
        DataConfig { env: EnvConfig { team_deadband: 0.5, ..team.env.clone() }, ..team.clone() };
    assert!(narrow.same_episodes(&team), "the dead band is read on replay");
    let a = generate(&bare, &|_| {}).unwrap().0;
    let b = generate(&team, &|_| {}).unwrap().0;
    assert_eq!(a.episodes, b.episodes);
    let mut widths = Vec::new();
    for_each_sample(&a.episodes[0], &team.env, team.leader_rule, |s| widths.push(s.vector.len()))
        .unwrap();
    assert!(!widths.is_empty() && widths.iter().all(|&w| w == 9), "{widths:?}");
    // Other episodes' settings, or a student's rollouts, are not the same episodes.
    assert!(!bare.same_episodes(&DataConfig { seed: 6, ..team.clone() }));
    let round = |config: &DataConfig| DataConfig {
        student: Some(StudentRollouts { round: 1, network: 7, epsilon: 0.0, stall_visits: 3 }),
        ..config.clone()
    };
    assert!(!round(&bare).same_episodes(&round(&team)));
    assert!(round(&team).same_episodes(&round(&team)));
}
