//! Shared helpers for the integration tests: proptest strategies for every message
//! variant, and a driver that feeds a byte stream through the decoder in chunks.
#![allow(dead_code)]

use bytes::{Bytes, BytesMut};
use proptest::prelude::*;
use protocol::{
    BinWidth, BlankingSector, Configuration, ConfigurationData, ContourUpdate, DecodeError,
    FftData, FrameDecoder, Message, NavigationData, NavigationTarget, RadarModel, SectorBlanking,
    Timestamp, CONTOUR_DEGREES,
};

/// Every id the crate decodes into a named variant.
pub const KNOWN_IDS: [u8; 19] = [
    1, 10, 20, 21, 22, 23, 24, 25, 30, 31, 40, 50, 51, 76, 120, 121, 122, 123, 140,
];

fn non_nan_f32() -> impl Strategy<Value = f32> {
    any::<f32>().prop_filter("NaN never compares equal", |x| !x.is_nan())
}

pub fn timestamp() -> impl Strategy<Value = Timestamp> {
    (any::<u32>(), 0u32..1_000_000_000).prop_map(|(s, n)| Timestamp::new(s, n).unwrap())
}

fn opt_string() -> impl Strategy<Value = Option<String>> {
    proptest::option::of("[ -~]{0,24}")
}

pub fn configuration_data() -> impl Strategy<Value = ConfigurationData> {
    let model = proptest::option::of(
        (
            proptest::option::of(any::<u32>()),
            opt_string(),
            opt_string(),
            proptest::option::of(non_nan_f32()),
            opt_string(),
        )
            .prop_map(
                |(id, name, uniqueid, rangeinmetres, profileid)| RadarModel {
                    id,
                    name,
                    uniqueid,
                    rangeinmetres,
                    profileid,
                },
            ),
    );
    let blob =
        proptest::option::of(proptest::collection::vec(any::<u8>(), 0..32).prop_map(Bytes::from));
    (
        (model, opt_string(), blob.clone(), blob),
        (
            proptest::option::of(non_nan_f32()),
            opt_string(),
            proptest::option::of(any::<i32>()),
            opt_string(),
            proptest::option::of(prop_oneof![Just(8), Just(16), any::<i32>()]),
            proptest::option::of(non_nan_f32()),
            proptest::option::of(0i32..8),
            proptest::option::of(any::<i32>()),
            opt_string(),
        ),
    )
        .prop_map(
            |(
                (model, macaddress, softwareversions, nvramcontents),
                (
                    rangeresolutionhz,
                    moduleserialnumber,
                    autotunevalue,
                    radaruniqueid,
                    datawidth,
                    rangeresolutionmetres,
                    radarfeatures,
                    staringmode,
                    onboardmacaddress,
                ),
            )| ConfigurationData {
                model,
                macaddress,
                softwareversions,
                nvramcontents,
                rangeresolutionhz,
                moduleserialnumber,
                autotunevalue,
                radaruniqueid,
                datawidth,
                rangeresolutionmetres,
                radarfeatures,
                staringmode,
                onboardmacaddress,
            },
        )
}

pub fn configuration() -> impl Strategy<Value = Configuration> {
    (
        any::<[u16; 6]>(),
        non_nan_f32(),
        non_nan_f32(),
        configuration_data(),
    )
        .prop_map(|(f, range_gain, range_offset_m, data)| Configuration {
            azimuth_samples: f[0],
            bin_size: f[1],
            range_in_bins: f[2],
            encoder_size: f[3],
            rotation_speed_millihertz: f[4],
            packet_rate: f[5],
            range_gain,
            range_offset_m,
            data,
        })
}

pub fn fft_data(max_bins: usize) -> impl Strategy<Value = FftData> {
    (
        prop_oneof![Just(BinWidth::Eight), Just(BinWidth::Sixteen)],
        prop_oneof![4 => Just(14u16), 1 => 14u16..40],
        any::<u16>(),
        any::<u16>(),
        timestamp(),
        proptest::collection::vec(any::<u8>(), 0..=max_bins),
    )
        .prop_map(
            |(width, fft_data_offset, sweep_counter, azimuth, timestamp, mut bins)| {
                if width == BinWidth::Sixteen && bins.len() % 2 == 1 {
                    bins.pop();
                }
                FftData {
                    width,
                    fft_data_offset,
                    sweep_counter,
                    azimuth,
                    timestamp,
                    bins: bins.into(),
                }
            },
        )
}

pub fn contour() -> impl Strategy<Value = ContourUpdate> {
    prop_oneof![
        Just(ContourUpdate::Reset),
        proptest::collection::vec(any::<u16>(), CONTOUR_DEGREES).prop_map(|v| {
            let boxed: Box<[u16; CONTOUR_DEGREES]> = v.into_boxed_slice().try_into().unwrap();
            ContourUpdate::MaxBinPerDegree(boxed)
        }),
    ]
}

pub fn sectors() -> impl Strategy<Value = SectorBlanking> {
    proptest::collection::vec(
        (non_nan_f32(), non_nan_f32()).prop_map(|(start_deg_x10, end_deg_x10)| BlankingSector {
            start_deg_x10,
            end_deg_x10,
        }),
        0..20,
    )
    .prop_map(|sectors| SectorBlanking { sectors })
}

pub fn navigation() -> impl Strategy<Value = NavigationData> {
    (
        any::<u16>(),
        timestamp(),
        proptest::collection::vec(
            (any::<u32>(), any::<u16>()).prop_map(|(range_um, power_db_x10)| NavigationTarget {
                range_um,
                power_db_x10,
            }),
            0..40,
        ),
    )
        .prop_map(|(azimuth, timestamp, targets)| NavigationData {
            azimuth,
            timestamp,
            targets,
        })
}

pub fn unknown() -> impl Strategy<Value = Message> {
    (
        any::<u8>().prop_filter("an unknown id", |id| !KNOWN_IDS.contains(id)),
        proptest::collection::vec(any::<u8>(), 0..64),
    )
        .prop_map(|(id, payload)| Message::Unknown {
            id,
            payload: payload.into(),
        })
}

/// Any message of any variant; FFT data up to `max_bins` bin bytes.
pub fn message(max_bins: usize) -> impl Strategy<Value = Message> {
    prop_oneof![
        1 => Just(Message::KeepAlive),
        1 => configuration().prop_map(|c| Message::Configuration(Box::new(c))),
        1 => Just(Message::ConfigurationRequest),
        1 => Just(Message::StartFftData),
        1 => Just(Message::StopFftData),
        1 => Just(Message::StartHealthMsgs),
        1 => Just(Message::StopHealthMsgs),
        1 => Just(Message::ResetRfHealth),
        4 => fft_data(max_bins).prop_map(Message::FftData),
        1 => proptest::collection::vec(any::<u8>(), 0..64).prop_map(|p| Message::Health(p.into())),
        1 => contour().prop_map(Message::ContourUpdate),
        1 => sectors().prop_map(Message::SectorBlankingUpdate),
        1 => Just(Message::SystemRestart),
        1 => Just(Message::StartNavData),
        1 => Just(Message::StopNavData),
        1 => any::<u16>().prop_map(|threshold_db_x10| Message::SetNavThreshold { threshold_db_x10 }),
        1 => navigation().prop_map(Message::NavigationData),
        1 => Just(Message::StartNonContourFftData),
        1 => unknown(),
    ]
}

/// What feeding a stream through the decoder produced.
#[derive(Debug, Default)]
pub struct Outcome {
    pub messages: Vec<Message>,
    pub errors: Vec<DecodeError>,
    pub left_over: usize,
}

/// Feeds `stream` to a fresh decoder in chunks of the given sizes (cycled; a zero size
/// counts as one), decoding until it asks for more after each chunk. Panics if a call
/// neither consumes bytes nor asks for more (which would loop forever).
pub fn feed(stream: &[u8], chunk_sizes: &[usize]) -> (Outcome, FrameDecoder) {
    let mut decoder = FrameDecoder::new();
    let mut buf = BytesMut::new();
    let mut out = Outcome::default();
    let mut pos = 0;
    let mut i = 0;
    let sizes = if chunk_sizes.is_empty() {
        &[usize::MAX][..]
    } else {
        chunk_sizes
    };
    while pos < stream.len() {
        let n = sizes[i % sizes.len()].max(1).min(stream.len() - pos);
        i += 1;
        buf.extend_from_slice(&stream[pos..pos + n]);
        pos += n;
        drain(&mut decoder, &mut buf, &mut out);
    }
    drain_eof(&mut decoder, &mut buf, &mut out);
    out.left_over = buf.len();
    (out, decoder)
}

/// Decodes from `buf` until the decoder needs more bytes.
pub fn drain(decoder: &mut FrameDecoder, buf: &mut BytesMut, out: &mut Outcome) {
    loop {
        let before = buf.len();
        match decoder.decode(buf) {
            Ok(Some(m)) => out.messages.push(m),
            Ok(None) => {
                assert_eq!(buf.len(), before, "Ok(None) consumes nothing");
                return;
            }
            Err(e) => out.errors.push(e),
        }
        assert!(buf.len() < before, "every Some or Err consumes bytes");
    }
}

/// At the end of the stream: decodes what is left with `decode_eof`.
pub fn drain_eof(decoder: &mut FrameDecoder, buf: &mut BytesMut, out: &mut Outcome) {
    loop {
        let before = buf.len();
        match decoder.decode_eof(buf) {
            Ok(Some(m)) => out.messages.push(m),
            Ok(None) => {
                assert_eq!(buf.len(), before, "Ok(None) consumes nothing");
                return;
            }
            Err(e) => out.errors.push(e),
        }
        assert!(buf.len() < before, "every Some or Err consumes bytes");
    }
}

/// Encodes messages back to back.
pub fn encode_all(messages: &[Message]) -> Vec<u8> {
    let mut buf = BytesMut::new();
    for m in messages {
        m.encode(&mut buf).unwrap();
    }
    buf.to_vec()
}
