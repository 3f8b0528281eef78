//! Replay: padding, windows with burn-in, terminated flags.

use phalanx_env::{ObsBuffers, ObsShape};
use phalanx_rl::{Episode, Replay, SequenceMode};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const SHAPE: ObsShape = ObsShape { channels: 1, fov: 1, env_vec: 1, n_actions: 5 };

/// An episode of `len` steps whose grid value is the step index; terminated if asked.
fn episode(len: usize, terminated: bool) -> Episode {
    let mut obs = ObsBuffers::new(1, SHAPE);
    let mut res = Episode::start(&obs);
    for t in 0..len {
        obs.grid[0] = (t + 1) as f32;
        res.push_step(&[3], t as f32, &obs);
    }
    res.terminated = terminated;
    res
}

#[test]
fn episodes_are_padded_with_a_filled_mask() {
    let mut replay = Replay::new(10, 1, SHAPE);
    replay.push(episode(2, true));
    replay.push(episode(4, false));
    let mut rng = ChaCha8Rng::seed_from_u64(0);
    let batch = (0..20)
        .map(|_| replay.sample(2, SequenceMode::Episodes, &mut rng))
        .find(|it| it.filled.iter().sum::<f32>() == 6.0)
        .expect("one batch with both episodes");
    assert_eq!(batch.len, 4);
    for b in 0..2 {
        let filled = &batch.filled[b * 4..(b + 1) * 4];
        let terminated = &batch.terminated[b * 4..(b + 1) * 4];
        if filled == [1.0, 1.0, 0.0, 0.0] {
            assert_eq!(terminated, [0.0, 1.0, 0.0, 0.0]);
        } else {
            assert_eq!(filled, [1.0; 4]);
            assert_eq!(terminated, [0.0; 4], "truncated episodes never set terminated");
        }
    }
}

#[test]
fn windows_have_burn_in_without_loss() {
    let mut replay = Replay::new(10, 1, SHAPE);
    replay.push(episode(20, true));
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..50 {
        let batch = replay.sample(1, SequenceMode::Windows { len: 4, burn_in: 3 }, &mut rng);
        assert_eq!(batch.len, 7);
        // The observation at sequence index 0 is episode step `from`.
        let from = batch.grid[0] as usize;
        let trained: Vec<usize> = (0..7).filter(|&t| batch.filled[t] == 1.0).collect();
        let start = trained[0];
        assert!(start <= 3, "burn-in is at most 3 steps");
        if start < 3 {
            assert_eq!(from, 0, "a short burn-in only at the episode start");
        }
        assert!(trained.len() <= 4 && trained.windows(2).all(|w| w[1] == w[0] + 1));
        for &t in &trained {
            // Rewards are the step index in the episode.
            assert_eq!(batch.rewards[t] as usize, from + t);
            let last = from + t == 19;
            assert_eq!(batch.terminated[t], if last { 1.0 } else { 0.0 });
        }
    }
}
