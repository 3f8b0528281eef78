//! The wire form: every message reads back as written, an action or a choice is 17 bytes, and
//! bad bytes are refused with the field they break.

use phalanx_msg::{
    Action, End, EndReason, Frame, Message, Near, Observation, VERSION, WireError, decode,
};
use proptest::prelude::*;

fn observation() -> Observation {
    Observation {
        episode: 7,
        step: 3,
        agent: 1,
        rank: 2,
        n_agents: 3,
        grid: vec![0.0, 1.0, -0.5, f32::MAX],
        vector: vec![0.25, -1.0, 3.0],
        mask: vec![true, false, true, true, false],
    }
}

fn frame() -> Frame {
    let near = vec![Near { agent: 0, dx: -1, dy: 1 }, Near { agent: 2, dx: 0, dy: -2 }];
    Frame { observation: observation(), choice: 1, near }
}

#[test]
fn messages_read_back_as_written() {
    let action = Action { episode: 1, step: 2, agent: 3, rank: 0, action: 4 };
    let choice = Action { action: 1, ..action };
    let end = End { episode: 1, steps: 60, reason: EndReason::StepLimit };
    for message in [
        Message::Observation(observation()),
        Message::Action(action),
        Message::End(end),
        Message::Meta(observation()),
        Message::Choice(choice),
        Message::Frame(frame()),
    ] {
        assert_eq!(decode(&message.encode()), Ok(message));
    }
    assert_eq!(Message::Action(action).encode().len(), 17, "an action is a few bytes");
    assert_eq!(Message::Choice(choice).encode().len(), 17, "a choice is an action's size");
    let observed = Message::Observation(observation()).encode().len();
    assert_eq!(Message::Frame(frame()).encode().len(), observed + 1 + 2 + 2 * 4);
}

#[test]
fn bad_hierarchy_messages_are_refused_naming_the_field() {
    let choice = Action { episode: 1, step: 2, agent: 0, rank: 0, action: 2 };
    assert_eq!(
        decode(&Message::Choice(choice).encode()),
        Err(WireError::Value { field: "choice", value: 2 })
    );
    let bad = |frame: Frame| decode(&Message::Frame(frame).encode());
    assert_eq!(
        bad(Frame { choice: 3, ..frame() }),
        Err(WireError::Value { field: "choice", value: 3 })
    );
    for (near, field, value) in [
        (Near { agent: 3, dx: 0, dy: 1 }, "near agent", 3),
        (Near { agent: 1, dx: 0, dy: 1 }, "near agent", 1),
        (Near { agent: 0, dx: -2, dy: 1 }, "near distance", 3),
    ] {
        let frame = Frame { near: vec![near], ..frame() };
        assert_eq!(bad(frame), Err(WireError::Value { field, value }), "{near:?}");
    }
    let bytes = Message::Frame(frame()).encode();
    let cut = decode(&bytes[..bytes.len() - 1]);
    assert!(matches!(cut, Err(WireError::Short { field: "near", .. })), "{cut:?}");
}

#[test]
fn bad_bytes_are_refused_naming_the_field() {
    let bytes = Message::Observation(observation()).encode();
    assert_eq!(decode(b"XY\x01\x02"), Err(WireError::Magic(*b"XY")));
    let mut other = bytes.clone();
    other[2] = VERSION + 1;
    assert_eq!(decode(&other), Err(WireError::Version { found: VERSION + 1 }));
    let mut kind = bytes.clone();
    kind[3] = 9;
    assert_eq!(decode(&kind), Err(WireError::Kind(9)));
    let cut = decode(&bytes[..bytes.len() - 2]);
    assert!(matches!(cut, Err(WireError::Short { field: "mask", .. })), "{cut:?}");
    let mut long = bytes.clone();
    long.push(0);
    assert_eq!(decode(&long), Err(WireError::Trailing(1)));
    let mut rank = Message::Observation(Observation { rank: 3, ..observation() }).encode();
    assert_eq!(decode(&rank), Err(WireError::Value { field: "rank", value: 3 }));
    rank.clear();
    assert!(matches!(decode(&rank), Err(WireError::Short { field: "magic", .. })));
}

proptest! {
    #[test]
    fn any_action_round_trips(episode: u32, step: u32, agent: u16, rank: u16, action: u8) {
        let message = Message::Action(Action { episode, step, agent, rank, action });
        prop_assert_eq!(decode(&message.encode()), Ok(message));
    }

    #[test]
    fn any_frame_round_trips(
        choice in 0_u8..2,
        near in proptest::collection::vec((0_u16..3, -1_i8..=1, -1_i8..=1), 0..4),
        grid in proptest::collection::vec(any::<f32>().prop_filter("a number", |x| !x.is_nan()), 0..8),
    ) {
        let near = near
            .into_iter()
            .filter(|&(agent, _, _)| agent != 1)
            .map(|(agent, dx, dy)| Near { agent, dx, dy })
            .collect();
        let observation = Observation { grid, ..observation() };
        let message = Message::Frame(Frame { observation, choice, near });
        prop_assert_eq!(decode(&message.encode()), Ok(message));
    }

    #[test]
    fn no_bytes_panic_the_decoder(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = decode(&bytes);
    }
}
