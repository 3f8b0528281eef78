//! The wire form: every message reads back as written, an action is 17 bytes, and bad bytes
//! are refused with the field they break.

use phalanx_msg::{Action, End, EndReason, Message, Observation, VERSION, WireError, decode};
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

#[test]
fn messages_read_back_as_written() {
    let action = Action { episode: 1, step: 2, agent: 3, rank: 0, action: 4 };
    let end = End { episode: 1, steps: 60, reason: EndReason::StepLimit };
    for message in [Message::Observation(observation()), Message::Action(action), Message::End(end)]
    {
        assert_eq!(decode(&message.encode()), Ok(message));
    }
    assert_eq!(Message::Action(action).encode().len(), 17, "an action is a few bytes");
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
    fn no_bytes_panic_the_decoder(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
        let _ = decode(&bytes);
    }
}
