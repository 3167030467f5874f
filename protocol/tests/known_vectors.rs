//! Known vectors: Navtech's worked configuration example, and a hand-built frame (literal
//! bytes) of every message type that must decode to known values and re-encode byte for
//! byte.

use bytes::{Bytes, BytesMut};
use protocol::{
    BinWidth, BlankingSector, Configuration, ContourUpdate, FftData, FrameDecoder, Message,
    NavigationData, NavigationTarget, SectorBlanking, Timestamp, CONTOUR_DEGREES,
};

const SIG: [u8; 16] = [
    0x00, 0x01, 0x03, 0x03, 0x07, 0x07, 0x0F, 0x0F, 0x1F, 0x1F, 0x3F, 0x3F, 0x7F, 0x7F, 0xFE, 0xFE,
];

/// Signature, version 1, id, BE size, payload.
fn frame(id: u8, payload: &[u8]) -> Vec<u8> {
    let mut f = SIG.to_vec();
    f.push(1);
    f.push(id);
    f.extend_from_slice(&u32::try_from(payload.len()).unwrap().to_be_bytes());
    f.extend_from_slice(payload);
    f
}

/// Decodes exactly one frame from `bytes`, checks it consumed everything, re-encodes it
/// and checks the bytes are identical.
fn decode_and_reencode(bytes: &[u8]) -> Message {
    let mut buf = BytesMut::from(bytes);
    let mut decoder = FrameDecoder::new();
    let msg = decoder
        .decode_eof(&mut buf)
        .expect("frame decodes")
        .expect("frame is whole");
    assert!(buf.is_empty(), "the frame was consumed exactly");
    let mut out = BytesMut::new();
    msg.encode(&mut out).expect("message encodes");
    assert_eq!(
        &out[..],
        bytes,
        "re-encoding reproduces the frame byte for byte"
    );
    assert_eq!(msg.encoded_len(), bytes.len());
    msg
}

const NAVTECH_FIXED_PART: [u8; 20] = [
    0x01, 0x90, 0x06, 0xD8, 0x0B, 0x28, 0x15, 0xE0, 0x0F, 0xA0, 0x06, 0x40, 0x3F, 0x7F, 0xEB, 0xC0,
    0xBE, 0xA3, 0xCB, 0x4B,
];

#[test]
fn navtechs_worked_configuration_example_decodes_to_its_values() {
    let config = Configuration::decode(&Bytes::from_static(&NAVTECH_FIXED_PART)).unwrap();
    assert_eq!(config.azimuth_samples, 400);
    assert_eq!(config.bin_size, 1752);
    assert_eq!(config.range_in_bins, 2856);
    assert_eq!(config.encoder_size, 5600);
    assert_eq!(config.rotation_speed_millihertz, 4000);
    assert_eq!(config.packet_rate, 1600);
    assert!((config.range_gain - 0.999_691).abs() < 1e-6);
    assert!((config.range_offset_m - -0.3199).abs() < 2e-5);
    assert_eq!(config.data, protocol::ConfigurationData::default());

    let g = config.geometry().unwrap();
    assert_eq!(
        g.data_width,
        BinWidth::Eight,
        "absent datawidth means 8 bits"
    );
    assert_eq!(g.rotation_hz, 4.0);
    assert!((g.bin_size_m - 0.1752).abs() < 1e-15);
    assert_eq!(g.encoder_step(), 14);
    assert!((g.azimuth_deg(1400) - 90.0).abs() < 1e-12);
    assert!((g.azimuth_step_rad() - 0.9f64.to_radians()).abs() < 1e-15);
    let r100 = g.bin_range_m(100.0);
    assert!((r100 - (0.999_691 * 17.52 - 0.3199)).abs() < 1e-4);
    assert!((g.range_m_to_bin(r100) - 100.0).abs() < 1e-9);
    assert_eq!(g.range_resolution_m, None);
}

#[test]
fn the_navtech_example_with_no_tail_reencodes_byte_for_byte() {
    let bytes = frame(10, &NAVTECH_FIXED_PART);
    assert!(matches!(
        decode_and_reencode(&bytes),
        Message::Configuration(_)
    ));
}

#[test]
fn a_configuration_with_a_protobuf_tail_decodes_and_reencodes() {
    let mut payload = NAVTECH_FIXED_PART.to_vec();
    // model { id: 1, name: "CTS350-X" }, datawidth 16, rangeresolutionmetres 0.1752.
    payload.extend_from_slice(&[
        0x0A, 0x0C, 0x08, 0x01, 0x12, 0x08, b'C', b'T', b'S', b'3', b'5', b'0', b'-', b'X',
    ]);
    payload.extend_from_slice(&[0x48, 0x10]);
    payload.extend_from_slice(&[0x55, 0xA1, 0x67, 0x33, 0x3E]);
    let bytes = frame(10, &payload);
    let Message::Configuration(config) = decode_and_reencode(&bytes) else {
        panic!("not a configuration");
    };
    let model = config.data.model.as_ref().unwrap();
    assert_eq!(model.id, Some(1));
    assert_eq!(model.name.as_deref(), Some("CTS350-X"));
    assert_eq!(config.data.datawidth, Some(16));
    assert_eq!(config.data.rangeresolutionmetres, Some(0.1752));
    let g = config.geometry().unwrap();
    assert_eq!(g.data_width, BinWidth::Sixteen);
    assert!((g.range_resolution_m.unwrap() - 0.1752).abs() < 1e-7);
}

#[test]
fn gain_and_resolution_ranges_agree_on_a_cts350x_configuration() {
    // CTS350-X: 3768 bins of 0.0438 m, gain 1, offset 0, resolution 0.0438 m.
    let config = Configuration {
        azimuth_samples: 400,
        bin_size: 438,
        range_in_bins: 3768,
        encoder_size: 5600,
        rotation_speed_millihertz: 4000,
        packet_rate: 1600,
        range_gain: 1.0,
        range_offset_m: 0.0,
        data: protocol::ConfigurationData::minimal(8, 0.0438),
    };
    let g = config.geometry().unwrap();
    for bin in [0.0, 1.0, 1000.0, 3767.0] {
        let a = g.bin_range_m(bin);
        let b = g.bin_range_m_by_resolution(bin).unwrap();
        assert!((a - b).abs() < 1e-4, "bin {bin}: {a} vs {b}");
    }
    assert!((g.max_range_m() - 165.0384).abs() < 1e-9);
}

#[test]
fn every_header_only_message_decodes_and_reencodes() {
    let cases = [
        (1, Message::KeepAlive),
        (20, Message::ConfigurationRequest),
        (21, Message::StartFftData),
        (22, Message::StopFftData),
        (23, Message::StartHealthMsgs),
        (24, Message::StopHealthMsgs),
        (25, Message::ResetRfHealth),
        (76, Message::SystemRestart),
        (120, Message::StartNavData),
        (121, Message::StopNavData),
        (140, Message::StartNonContourFftData),
    ];
    for (id, expected) in cases {
        let bytes = frame(id, &[]);
        assert_eq!(bytes.len(), 22);
        assert_eq!(decode_and_reencode(&bytes), expected, "id {id}");
        assert_eq!(expected.id(), id);
    }
}

#[test]
fn an_8_bit_fft_frame_decodes_to_its_fields_and_half_db_bins() {
    #[rustfmt::skip]
    let bytes: Vec<u8> = [
        &SIG[..], &[0x01, 0x1E, 0x00, 0x00, 0x00, 0x12],
        &[0x00, 0x0E, 0x00, 0x07, 0x05, 0x78],
        &[0x00, 0x10, 0x5E, 0x5F], &[0x00, 0x65, 0xCD, 0x1D],
        &[0x00, 0xB5, 0xFF, 0x10],
    ].concat();
    let msg = decode_and_reencode(&bytes);
    let expected = FftData::new(
        BinWidth::Eight,
        7,
        1400,
        Timestamp::new(1_600_000_000, 500_000_000).unwrap(),
        Bytes::from_static(&[0x00, 0xB5, 0xFF, 0x10]),
    );
    assert_eq!(msg, Message::FftData(expected));
    let Message::FftData(fft) = msg else {
        unreachable!()
    };
    assert_eq!(fft.bin_count(), 4);
    assert_eq!(fft.bins_db().collect::<Vec<_>>(), [0.0, 90.5, 127.5, 8.0]);
    assert_eq!(fft.timestamp.as_secs_f64(), 1_600_000_000.5);
}

#[test]
fn a_16_bit_fft_frame_reads_little_endian_bins() {
    #[rustfmt::skip]
    let bytes: Vec<u8> = [
        &SIG[..], &[0x01, 0x1F, 0x00, 0x00, 0x00, 0x12],
        &[0x00, 0x0E, 0xFF, 0xFF, 0x15, 0xD4],
        &[0x00, 0x10, 0x5E, 0x5F], &[0x00, 0x65, 0xCD, 0x1D],
        &[0x80, 0x8D, 0x01, 0x00],
    ].concat();
    let Message::FftData(fft) = decode_and_reencode(&bytes) else {
        panic!("not FFT data")
    };
    assert_eq!(fft.width, BinWidth::Sixteen);
    assert_eq!(fft.sweep_counter, 65535);
    assert_eq!(fft.azimuth, 5588);
    assert_eq!(fft.bin_count(), 2);
    assert_eq!(fft.bin_raw(0), Some(36_224));
    assert_eq!(fft.bin_raw(1), Some(1));
    assert_eq!(fft.bin_raw(2), None);
    assert!((fft.power_db(0).unwrap() - 96.5).abs() < 1e-12);
}

#[test]
fn an_fft_frame_with_a_larger_data_offset_skips_the_extra_header_bytes() {
    #[rustfmt::skip]
    let bytes: Vec<u8> = [
        &SIG[..], &[0x01, 0x1E, 0x00, 0x00, 0x00, 0x12],
        &[0x00, 0x10, 0x00, 0x01, 0x00, 0x0E],
        &[0x00, 0x10, 0x5E, 0x5F], &[0x00, 0x65, 0xCD, 0x1D],
        &[0x00, 0x00, 0x42, 0x43],
    ].concat();
    let Message::FftData(fft) = decode_and_reencode(&bytes) else {
        panic!("not FFT data")
    };
    assert_eq!(fft.fft_data_offset, 16);
    assert_eq!(&fft.bins[..], &[0x42, 0x43]);
}

#[test]
fn a_blanked_azimuth_with_zero_bins_decodes() {
    #[rustfmt::skip]
    let bytes: Vec<u8> = [
        &SIG[..], &[0x01, 0x1E, 0x00, 0x00, 0x00, 0x0E],
        &[0x00, 0x0E, 0x00, 0x01, 0x00, 0x0E],
        &[0x00, 0x10, 0x5E, 0x5F], &[0x00, 0x65, 0xCD, 0x1D],
    ].concat();
    let Message::FftData(fft) = decode_and_reencode(&bytes) else {
        panic!("not FFT data")
    };
    assert_eq!(fft.bin_count(), 0);
}

#[test]
fn a_health_frame_keeps_its_protobuf_opaque() {
    let bytes = frame(40, &[0x0A, 0x01, 0x41]);
    assert_eq!(
        decode_and_reencode(&bytes),
        Message::Health(Bytes::from_static(&[0x0A, 0x01, 0x41]))
    );
}

#[test]
fn contour_updates_reset_when_empty_and_carry_360_big_endian_bins() {
    assert_eq!(
        decode_and_reencode(&frame(50, &[])),
        Message::ContourUpdate(ContourUpdate::Reset)
    );
    let mut payload = Vec::new();
    for degree in 0..360u16 {
        payload.extend_from_slice(&(degree * 10 + 1).to_be_bytes());
    }
    let Message::ContourUpdate(ContourUpdate::MaxBinPerDegree(bins)) =
        decode_and_reencode(&frame(50, &payload))
    else {
        panic!("not a contour")
    };
    assert_eq!(bins.len(), CONTOUR_DEGREES);
    assert_eq!(bins[0], 1);
    assert_eq!(bins[359], 3591);
}

#[test]
fn a_sector_blanking_update_decodes_its_tenths_of_degrees() {
    #[rustfmt::skip]
    let payload = [
        0x02,
        0x00, 0x00, 0x00, 0x00, 0x42, 0xC8, 0x00, 0x00,
        0x44, 0x61, 0x00, 0x00, 0x44, 0x7A, 0x00, 0x00,
    ];
    let msg = decode_and_reencode(&frame(51, &payload));
    let expected = SectorBlanking {
        sectors: vec![
            BlankingSector::from_degrees(0.0, 10.0),
            BlankingSector::from_degrees(90.0, 100.0),
        ],
    };
    assert_eq!(msg, Message::SectorBlankingUpdate(expected));
    let Message::SectorBlankingUpdate(s) = msg else {
        unreachable!()
    };
    assert_eq!(s.sectors[1].start_deg(), 90.0);
}

#[test]
fn a_navigation_threshold_is_tenths_of_a_db_big_endian() {
    assert_eq!(
        decode_and_reencode(&frame(122, &[0x03, 0x84])),
        Message::SetNavThreshold {
            threshold_db_x10: 900
        }
    );
}

#[test]
fn navigation_data_decodes_targets_in_metres_and_db() {
    #[rustfmt::skip]
    let payload = [
        0x05, 0x78, 0x5F, 0x5E, 0x10, 0x00, 0x1D, 0xCD, 0x65, 0x00,
        0x00, 0x98, 0x96, 0x80, 0x03, 0x84,
        0x01, 0x31, 0x2D, 0x00, 0x02, 0x58,
    ];
    let msg = decode_and_reencode(&frame(123, &payload));
    let expected = NavigationData {
        azimuth: 1400,
        timestamp: Timestamp::new(1_600_000_000, 500_000_000).unwrap(),
        targets: vec![
            NavigationTarget {
                range_um: 10_000_000,
                power_db_x10: 900,
            },
            NavigationTarget {
                range_um: 20_000_000,
                power_db_x10: 600,
            },
        ],
    };
    assert_eq!(msg, Message::NavigationData(expected));
    let Message::NavigationData(nav) = msg else {
        unreachable!()
    };
    assert_eq!(nav.targets[0].range_m(), 10.0);
    assert_eq!(nav.targets[1].power_db(), 60.0);
}

#[test]
fn an_unknown_id_keeps_its_payload() {
    assert_eq!(
        decode_and_reencode(&frame(99, &[0xDE, 0xAD])),
        Message::Unknown {
            id: 99,
            payload: Bytes::from_static(&[0xDE, 0xAD])
        }
    );
}
