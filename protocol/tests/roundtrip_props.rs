//! Property tests: encode then decode is the identity for every message variant, and any
//! chunking of a stream of many frames yields the same frames.

mod common;

use bytes::BytesMut;
use common::{encode_all, feed, message};
use proptest::prelude::*;
use protocol::{FrameDecoder, Message};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn encoding_then_decoding_any_message_gives_it_back(msg in message(4000)) {
        let mut buf = BytesMut::new();
        msg.encode(&mut buf).unwrap();
        prop_assert_eq!(buf.len(), msg.encoded_len());
        let wire = buf.clone().freeze();
        let mut decoder = FrameDecoder::new();
        let decoded = decoder.decode_eof(&mut buf).unwrap().unwrap();
        prop_assert!(buf.is_empty());
        prop_assert_eq!(&decoded, &msg);
        // And the decoded message re-encodes to the same bytes.
        let mut again = BytesMut::new();
        decoded.encode(&mut again).unwrap();
        prop_assert_eq!(&again[..], &wire[..]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn any_split_of_a_stream_of_frames_yields_the_same_frames(
        messages in proptest::collection::vec(message(600), 1..30),
        chunk_sizes in proptest::collection::vec(1usize..300, 1..40),
    ) {
        let stream = encode_all(&messages);
        let (out, decoder) = feed(&stream, &chunk_sizes);
        prop_assert!(out.errors.is_empty(), "errors: {:?}", out.errors);
        prop_assert_eq!(out.left_over, 0);
        prop_assert_eq!(&out.messages, &messages);
        prop_assert_eq!(decoder.stats().bytes_decoded, stream.len() as u64);
    }

    #[test]
    fn byte_at_a_time_delivery_yields_the_same_frames(
        messages in proptest::collection::vec(message(100), 1..8),
    ) {
        let stream = encode_all(&messages);
        let (out, _) = feed(&stream, &[1]);
        prop_assert_eq!(&out.messages, &messages);
    }
}

#[test]
fn the_strategy_reaches_every_variant() {
    use proptest::strategy::ValueTree;
    use proptest::test_runner::TestRunner;
    let mut runner = TestRunner::deterministic();
    let strategy = message(16);
    let mut seen = std::collections::BTreeSet::new();
    for _ in 0..5000 {
        let m: Message = strategy.new_tree(&mut runner).unwrap().current();
        seen.insert(match m {
            Message::Unknown { .. } => 0,
            other => other.id(),
        });
    }
    for id in common::KNOWN_IDS {
        assert!(seen.contains(&id), "variant with id {id} never generated");
    }
    assert!(seen.contains(&0), "Unknown never generated");
}
