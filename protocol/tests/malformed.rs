//! Every malformed payload maps to its named error variant, and costs only its frame.

use bytes::BytesMut;
use protocol::{
    encode_raw_frame, BinWidth, DecodeError, EncodeError, FftData, FrameDecoder, Message,
    PayloadError, SectorBlanking, Timestamp,
};

fn decode_payload(id: u8, payload: &[u8]) -> Result<Message, PayloadError> {
    Message::decode_payload(id, bytes::Bytes::copy_from_slice(payload))
}

fn fft_payload(offset: u16, nanos: u32, bins: &[u8]) -> Vec<u8> {
    let mut p = offset.to_be_bytes().to_vec();
    p.extend_from_slice(&[0, 1, 0, 14]);
    p.extend_from_slice(&1_600_000_000u32.to_le_bytes());
    p.extend_from_slice(&nanos.to_le_bytes());
    p.extend_from_slice(bins);
    p
}

#[test]
fn a_truncated_fft_header_is_a_truncated_payload() {
    assert_eq!(
        decode_payload(30, &[0, 14, 0, 1]),
        Err(PayloadError::Truncated { needed: 6, got: 4 })
    );
}

#[test]
fn an_fft_data_offset_beyond_the_payload_is_named() {
    assert_eq!(
        decode_payload(30, &fft_payload(40, 0, &[1, 2, 3])),
        Err(PayloadError::FftDataOffsetBeyondPayload {
            offset: 40,
            payload_len: 17
        })
    );
}

#[test]
fn an_fft_data_offset_inside_the_fft_header_is_named() {
    assert_eq!(
        decode_payload(30, &fft_payload(10, 0, &[1, 2, 3])),
        Err(PayloadError::FftDataOffsetTooSmall { offset: 10 })
    );
}

#[test]
fn an_odd_number_of_16_bit_bin_bytes_is_named() {
    assert_eq!(
        decode_payload(31, &fft_payload(14, 0, &[1, 2, 3])),
        Err(PayloadError::OddBinPayload { len: 3 })
    );
    // The same bytes are fine as 8-bit bins.
    assert!(decode_payload(30, &fft_payload(14, 0, &[1, 2, 3])).is_ok());
}

#[test]
fn nanoseconds_of_a_second_or_more_are_named() {
    assert_eq!(
        decode_payload(30, &fft_payload(14, 1_000_000_000, &[])),
        Err(PayloadError::BadNanos {
            nanos: 1_000_000_000
        })
    );
}

#[test]
fn a_configuration_shorter_than_its_fixed_part_is_truncated() {
    assert!(matches!(
        decode_payload(10, &[0; 19]),
        Err(PayloadError::Truncated { got: 19, .. })
    ));
}

#[test]
fn a_configuration_with_a_broken_protobuf_is_a_protobuf_error() {
    let mut p = vec![0u8; 20];
    p.extend_from_slice(&[0x0A, 0x05, 0x01]); // field 1, length 5, only 1 byte
    assert!(matches!(
        decode_payload(10, &p),
        Err(PayloadError::Protobuf(_))
    ));
}

#[test]
fn a_sector_count_that_disagrees_with_the_length_is_named() {
    assert_eq!(
        decode_payload(51, &[2, 0, 0, 0, 0, 0, 0, 0, 0]),
        Err(PayloadError::BadSectorCount {
            count: 2,
            payload_len: 9
        })
    );
    assert_eq!(
        decode_payload(51, &[]),
        Err(PayloadError::Truncated { needed: 1, got: 0 })
    );
}

#[test]
fn a_contour_of_the_wrong_length_is_named() {
    assert_eq!(
        decode_payload(50, &[0; 718]),
        Err(PayloadError::BadContourLength { len: 718 })
    );
}

#[test]
fn navigation_targets_must_be_whole() {
    assert_eq!(
        decode_payload(123, &[0; 15]),
        Err(PayloadError::BadNavigationTargets { len: 5 })
    );
}

#[test]
fn a_header_only_message_with_a_payload_is_the_wrong_length() {
    assert_eq!(
        decode_payload(1, &[0]),
        Err(PayloadError::WrongLength {
            expected: 0,
            got: 1
        })
    );
    assert_eq!(
        decode_payload(122, &[0]),
        Err(PayloadError::WrongLength {
            expected: 2,
            got: 1
        })
    );
}

#[test]
fn a_malformed_frame_in_a_stream_is_reported_with_its_id_and_the_next_one_decodes() {
    let mut buf = BytesMut::new();
    encode_raw_frame(&mut buf, 31, &fft_payload(14, 0, &[1, 2, 3])).unwrap();
    Message::KeepAlive.encode(&mut buf).unwrap();
    let mut d = FrameDecoder::new();
    assert_eq!(
        d.decode(&mut buf),
        Err(DecodeError::Payload {
            message_id: 31,
            source: PayloadError::OddBinPayload { len: 3 }
        })
    );
    assert_eq!(d.decode(&mut buf), Ok(Some(Message::KeepAlive)));
    assert_eq!(d.stats().frames_rejected(), 1);
}

#[test]
fn encoding_refuses_what_no_receiver_would_accept_and_writes_nothing() {
    let mut dst = BytesMut::new();
    let ts = Timestamp::EPOCH;
    let odd = FftData::new(BinWidth::Sixteen, 0, 0, ts, bytes::Bytes::from_static(&[1]));
    assert_eq!(
        Message::FftData(odd).encode(&mut dst),
        Err(EncodeError::OddBinBytes { len: 1 })
    );
    let huge = FftData::new(BinWidth::Eight, 0, 0, ts, vec![0u8; 999_986].into());
    assert!(matches!(
        Message::FftData(huge).encode(&mut dst),
        Err(EncodeError::PayloadTooLarge {
            message_id: 30,
            payload_len: 1_000_000
        })
    ));
    let mut low = FftData::new(BinWidth::Eight, 0, 0, ts, bytes::Bytes::new());
    low.fft_data_offset = 13;
    assert_eq!(
        Message::FftData(low).encode(&mut dst),
        Err(EncodeError::FftDataOffsetTooSmall { offset: 13 })
    );
    let many = SectorBlanking {
        sectors: vec![protocol::BlankingSector::from_degrees(0.0, 1.0); 256],
    };
    assert_eq!(
        Message::SectorBlankingUpdate(many).encode(&mut dst),
        Err(EncodeError::TooManySectors { count: 256 })
    );
    assert!(dst.is_empty());
}

#[test]
fn quantising_a_non_finite_power_is_an_error_that_writes_nothing() {
    let mut dst = BytesMut::from(&b"keep"[..]);
    let err = protocol::encode_fft_frame_from_db(
        &mut dst,
        BinWidth::Eight,
        0,
        0,
        Timestamp::EPOCH,
        [1.0, f64::NAN, 2.0],
    );
    assert!(matches!(
        err,
        Err(EncodeError::NonFinitePower { index: 1, .. })
    ));
    assert_eq!(&dst[..], b"keep");
}
