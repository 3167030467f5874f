//! Property tests on hostile streams: arbitrary bytes never panic and never loop, and
//! garbage between frames costs only the garbage.

mod common;

use common::{encode_all, feed, message};
use proptest::prelude::*;
use protocol::{DecodeError, SIGNATURE};

/// Garbage that does not contain a whole signature, in several flavours: random bytes, a
/// truncated signature, a header with a bad version, a header with an oversized length.
fn garbage() -> impl Strategy<Value = Vec<u8>> {
    let random = proptest::collection::vec(any::<u8>(), 1..200);
    let truncated_signature = (1usize..16, proptest::collection::vec(any::<u8>(), 0..8))
        .prop_map(|(n, tail)| [&SIGNATURE[..n], &tail[..]].concat());
    let bad_version = (
        any::<u8>().prop_filter("not version 1", |v| *v != 1),
        proptest::collection::vec(any::<u8>(), 0..30),
    )
        .prop_map(|(v, tail)| [&SIGNATURE[..], &[v], &tail[..]].concat());
    let oversized = (
        any::<u8>(),
        1_000_000u32..=u32::MAX,
        proptest::collection::vec(any::<u8>(), 0..30),
    )
        .prop_map(|(id, size, tail)| {
            [&SIGNATURE[..], &[1, id], &size.to_be_bytes()[..], &tail[..]].concat()
        });
    prop_oneof![random, truncated_signature, bad_version, oversized]
        .prop_filter("no whole signature after the first byte", |g| {
            g.len() < 2 || !g[1..].windows(16).any(|w| w == SIGNATURE)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    #[test]
    fn arbitrary_bytes_never_panic_or_stall(
        bytes in proptest::collection::vec(any::<u8>(), 0..3000),
        chunk_sizes in proptest::collection::vec(1usize..500, 1..10),
    ) {
        let (out, decoder) = feed(&bytes, &chunk_sizes);
        prop_assert_eq!(
            decoder.stats().bytes_consumed() + out.left_over as u64,
            bytes.len() as u64
        );
    }

    #[test]
    fn random_bytes_behind_a_real_signature_never_panic(
        id in any::<u8>(),
        size in 0u32..2000,
        body in proptest::collection::vec(any::<u8>(), 0..2000),
    ) {
        let stream = [&SIGNATURE[..], &[1, id], &size.to_be_bytes()[..], &body[..]].concat();
        let (out, decoder) = feed(&stream, &[7, 300, 1]);
        prop_assert_eq!(
            decoder.stats().bytes_consumed() + out.left_over as u64,
            stream.len() as u64
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn garbage_between_frames_costs_only_the_garbage(
        parts in proptest::collection::vec((garbage(), message(300)), 1..15),
        chunk_sizes in proptest::collection::vec(1usize..400, 1..20),
    ) {
        let mut stream = Vec::new();
        let mut garbage_len = 0u64;
        let mut messages = Vec::new();
        for (g, m) in &parts {
            stream.extend_from_slice(g);
            garbage_len += g.len() as u64;
            stream.extend_from_slice(&encode_all(std::slice::from_ref(m)));
            messages.push(m.clone());
        }
        let (out, decoder) = feed(&stream, &chunk_sizes);
        prop_assert_eq!(&out.messages, &messages);
        prop_assert_eq!(out.left_over, 0);
        prop_assert_eq!(decoder.stats().bytes_skipped, garbage_len);
        let no_frame_rejected = out.errors.iter().all(|e| !matches!(e, DecodeError::Payload { .. }));
        prop_assert!(no_frame_rejected, "errors: {:?}", out.errors);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn a_frame_cut_short_by_the_next_costs_only_itself(
        parts in proptest::collection::vec(
            (proptest::option::of((message(300), any::<prop::sample::Index>())), message(300)),
            1..12,
        ),
        chunk_sizes in proptest::collection::vec(1usize..400, 1..20),
    ) {
        let mut stream = Vec::new();
        let mut complete = Vec::new();
        let mut complete_len = 0u64;
        for (stub, m) in &parts {
            if let Some((cut, at)) = stub {
                let bytes = encode_all(std::slice::from_ref(cut));
                // Cut anywhere after the first byte and at least two bytes before the end
                // (a frame cut one byte short is documented to cost the next frame too).
                let keep = 1 + at.index(bytes.len() - 2);
                stream.extend_from_slice(&bytes[..keep]);
            }
            let bytes = encode_all(std::slice::from_ref(m));
            complete_len += bytes.len() as u64;
            stream.extend_from_slice(&bytes);
            complete.push(m.clone());
        }
        let (out, decoder) = feed(&stream, &chunk_sizes);
        prop_assert_eq!(&out.messages, &complete);
        prop_assert_eq!(decoder.stats().bytes_decoded, complete_len);
        prop_assert_eq!(out.left_over, 0);
    }
}
