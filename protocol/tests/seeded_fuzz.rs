//! A stable-toolchain stand-in for the cargo-fuzz target (`fuzz/fuzz_targets/decoder.rs`)
//! that CI runs: 200,000 deterministic (seeded) byte streams built from valid frames,
//! mutated frames and garbage, fed through the decoder in random chunks.
//!
//! Checked for every stream: no panic; every call consumes bytes or asks for more (no
//! stall); every byte is accounted for (decoded + skipped + rejected + left over = fed);
//! every decoded message re-encodes to bytes that decode to the same bytes again.

mod common;

use bytes::{Bytes, BytesMut};
use common::{drain, drain_eof, Outcome};
use protocol::{
    BinWidth, BlankingSector, Configuration, ConfigurationData, ContourUpdate, DecodeError,
    FftData, FrameDecoder, Message, NavigationData, NavigationTarget, PayloadError, SectorBlanking,
    Timestamp, HEADER_LEN,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const STREAMS: usize = 200_000;
const SEED: u64 = 0x6317_0001;

/// One valid frame of every message type, plus a few sizes of FFT data.
fn corpus() -> Vec<Vec<u8>> {
    let ts = Timestamp::new(1_600_000_000, 123_456_789).unwrap();
    let config = Configuration {
        azimuth_samples: 400,
        bin_size: 438,
        range_in_bins: 3768,
        encoder_size: 5600,
        rotation_speed_millihertz: 4000,
        packet_rate: 1600,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data: ConfigurationData::minimal(8, 0.0438),
    };
    let bins: Vec<u8> = (0..200u8).collect();
    let messages = vec![
        Message::KeepAlive,
        Message::Configuration(Box::new(config)),
        Message::ConfigurationRequest,
        Message::StartFftData,
        Message::StopFftData,
        Message::StartHealthMsgs,
        Message::StopHealthMsgs,
        Message::ResetRfHealth,
        Message::FftData(FftData::new(
            BinWidth::Eight,
            1,
            14,
            ts,
            Bytes::from(bins.clone()),
        )),
        Message::FftData(FftData::new(
            BinWidth::Sixteen,
            2,
            28,
            ts,
            Bytes::from(bins),
        )),
        Message::FftData(FftData::new(BinWidth::Eight, 3, 42, ts, Bytes::new())),
        Message::Health(Bytes::from_static(&[0x0A, 0x02, 0x08, 0x01])),
        Message::ContourUpdate(ContourUpdate::Reset),
        Message::ContourUpdate(ContourUpdate::MaxBinPerDegree(Box::new([3768; 360]))),
        Message::SectorBlankingUpdate(SectorBlanking {
            sectors: vec![BlankingSector::from_degrees(10.0, 20.0)],
        }),
        Message::SystemRestart,
        Message::StartNavData,
        Message::StopNavData,
        Message::SetNavThreshold {
            threshold_db_x10: 600,
        },
        Message::NavigationData(NavigationData {
            azimuth: 14,
            timestamp: ts,
            targets: vec![NavigationTarget {
                range_um: 12_345_678,
                power_db_x10: 700,
            }],
        }),
        Message::StartNonContourFftData,
        Message::Unknown {
            id: 99,
            payload: Bytes::from_static(b"xyz"),
        },
    ];
    messages
        .iter()
        .map(|m| m.to_bytes().unwrap().to_vec())
        .collect()
}

const INTERESTING_U32: [u32; 8] = [0, 1, 13, 14, 999_999, 1_000_000, 0x7FFF_FFFF, u32::MAX];

/// Mutates one frame in one of several ways a broken link or a hostile peer might.
fn mutate(rng: &mut ChaCha8Rng, frame: &mut Vec<u8>) {
    if frame.is_empty() {
        return;
    }
    match rng.gen_range(0..8) {
        0 => {
            for _ in 0..rng.gen_range(1..5) {
                let i = rng.gen_range(0..frame.len());
                frame[i] ^= 1 << rng.gen_range(0..8);
            }
        }
        1 => {
            let i = rng.gen_range(0..frame.len());
            frame[i] = [0x00, 0x01, 0x7F, 0x80, 0xFE, 0xFF][rng.gen_range(0..6)];
        }
        2 => frame.truncate(rng.gen_range(0..frame.len())),
        3 if frame.len() >= HEADER_LEN => {
            let size = if rng.gen_bool(0.5) {
                INTERESTING_U32[rng.gen_range(0..INTERESTING_U32.len())]
            } else {
                let len = u32::try_from(frame.len() - HEADER_LEN).unwrap();
                len.saturating_add_signed(rng.gen_range(-20..20))
            };
            frame[18..22].copy_from_slice(&size.to_be_bytes());
        }
        4 if frame.len() >= HEADER_LEN => frame[17] = rng.gen(),
        5 if frame.len() >= HEADER_LEN => frame[16] = rng.gen(),
        6 if frame.len() > HEADER_LEN + 4 => {
            // Payload fields: FFT data offset, sector count, and the like.
            let i = rng.gen_range(HEADER_LEN..frame.len() - 1);
            let v: u16 = [0, 13, 14, 15, 0xFFFF, rng.gen()][rng.gen_range(0..6)];
            frame[i..i + 2].copy_from_slice(&v.to_be_bytes());
        }
        _ => {
            let at = rng.gen_range(0..=frame.len());
            let junk: Vec<u8> = (0..rng.gen_range(1..16)).map(|_| rng.gen()).collect();
            frame.splice(at..at, junk);
        }
    }
}

fn build_stream(rng: &mut ChaCha8Rng, corpus: &[Vec<u8>]) -> Vec<u8> {
    let mut stream = Vec::new();
    for _ in 0..rng.gen_range(1..6) {
        let mut piece = corpus[rng.gen_range(0..corpus.len())].clone();
        match rng.gen_range(0..10) {
            0..=3 => {}
            4..=8 => mutate(rng, &mut piece),
            _ => piece = (0..rng.gen_range(0..64)).map(|_| rng.gen()).collect(),
        }
        stream.extend_from_slice(&piece);
    }
    stream
}

#[derive(Debug, Default)]
struct Totals {
    bytes: u64,
    decoded: u64,
    bad_signature: u64,
    bad_version: u64,
    oversized: u64,
    bad_payload: u64,
    cut_short: u64,
}

fn check_reencoding(m: &Message) {
    let first = m.to_bytes().expect("a decoded message encodes");
    let mut buf = BytesMut::from(&first[..]);
    let again = FrameDecoder::new()
        .decode_eof(&mut buf)
        .expect("its encoding decodes")
        .expect("whole");
    assert_eq!(again.to_bytes().unwrap(), first, "encoding is stable");
}

#[test]
fn two_hundred_thousand_seeded_hostile_streams_never_panic_stall_or_lose_count() {
    let corpus = corpus();
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut totals = Totals::default();
    for _ in 0..STREAMS {
        let stream = build_stream(&mut rng, &corpus);
        let mut decoder = FrameDecoder::new();
        let mut buf = BytesMut::new();
        let mut out = Outcome::default();
        let mut pos = 0;
        while pos < stream.len() {
            let n = rng.gen_range(1..=stream.len() - pos);
            buf.extend_from_slice(&stream[pos..pos + n]);
            pos += n;
            drain(&mut decoder, &mut buf, &mut out);
        }
        drain_eof(&mut decoder, &mut buf, &mut out);
        let stats = decoder.stats();
        assert_eq!(
            stats.bytes_consumed() + buf.len() as u64,
            stream.len() as u64
        );
        assert_eq!(stats.frames_decoded, out.messages.len() as u64);
        for m in &out.messages {
            check_reencoding(m);
        }
        totals.bytes += stream.len() as u64;
        totals.decoded += stats.frames_decoded;
        for e in &out.errors {
            match e {
                DecodeError::BadSignature { .. } => totals.bad_signature += 1,
                DecodeError::BadVersion { .. } => totals.bad_version += 1,
                DecodeError::Oversized { .. } => totals.oversized += 1,
                DecodeError::Payload {
                    source: PayloadError::CutShort { .. },
                    ..
                } => totals.cut_short += 1,
                DecodeError::Payload { .. } => totals.bad_payload += 1,
            }
        }
    }
    println!("{STREAMS} streams: {totals:?}");
    // The corpus and mutations must exercise every path, or this test proves little.
    assert!(totals.decoded > 100_000);
    assert!(totals.bad_signature > 10_000);
    assert!(totals.bad_version > 1_000);
    assert!(totals.oversized > 1_000);
    assert!(totals.bad_payload > 1_000);
    assert!(totals.cut_short > 1_000);
}
