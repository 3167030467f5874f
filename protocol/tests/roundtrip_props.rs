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

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn powers_encoded_from_db_decode_to_within_half_a_quantisation_step(
        sixteen in any::<bool>(),
        powers in proptest::collection::vec(0.0f64..120.0, 0..600),
        sweep in any::<u16>(),
        azimuth in any::<u16>(),
    ) {
        let width = if sixteen { protocol::BinWidth::Sixteen } else { protocol::BinWidth::Eight };
        let step_db = if sixteen { protocol::units::BIN16_DB_SCALE / 256.0 } else { 0.5 };
        let ts = protocol::Timestamp::new(1_700_000_000, 1).unwrap();
        let mut buf = BytesMut::new();
        protocol::encode_fft_frame_from_db(&mut buf, width, sweep, azimuth, ts, powers.iter().copied())
            .unwrap();
        let Some(Message::FftData(fft)) = FrameDecoder::new().decode_eof(&mut buf).unwrap() else {
            panic!("not FFT data");
        };
        prop_assert_eq!((fft.sweep_counter, fft.azimuth, fft.timestamp), (sweep, azimuth, ts));
        prop_assert_eq!(fft.bin_count(), powers.len());
        for (got, want) in fft.bins_db().zip(&powers) {
            prop_assert!((got - want).abs() <= step_db / 2.0 + 1e-9, "{} vs {}", got, want);
        }
        // The f32 fast path gives the same values, rounded to f32.
        let mut db32 = Vec::new();
        fft.bins_db_into(&mut db32);
        let expected: Vec<f32> = fft.bins_db().map(|d| d as f32).collect();
        prop_assert_eq!(db32, expected);
    }
}
