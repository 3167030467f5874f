//! Every Colossus message as one enum, with its payload decoder and its encoder
//! (`docs/colossus-protocol.md`, section 2).

use bytes::{BufMut, Bytes, BytesMut};

use crate::configuration::Configuration;
use crate::contour::ContourUpdate;
use crate::error::{EncodeError, PayloadError};
use crate::fft::{BinWidth, FftData};
use crate::frame::{checked_payload_size, encode_header, HEADER_LEN};
use crate::navigation::NavigationData;
use crate::sectors::SectorBlanking;

pub use crate::ids::message_id;

/// One Colossus message.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// 1: keep alive (empty).
    KeepAlive,
    /// 10: configuration.
    Configuration(Box<Configuration>),
    /// 20: configuration request (empty).
    ConfigurationRequest,
    /// 21: start FFT data (empty).
    StartFftData,
    /// 22: stop FFT data (empty).
    StopFftData,
    /// 23: start health messages (empty).
    StartHealthMsgs,
    /// 24: stop health messages (empty).
    StopHealthMsgs,
    /// 25: reset RF health (empty).
    ResetRfHealth,
    /// 30 (8-bit bins) or 31 (16-bit bins): one azimuth of FFT data.
    FftData(FftData),
    /// 40: health; the `Health` protobuf kept opaque.
    Health(Bytes),
    /// 50: contour update.
    ContourUpdate(ContourUpdate),
    /// 51: sector blanking update.
    SectorBlankingUpdate(SectorBlanking),
    /// 76: system restart (empty).
    SystemRestart,
    /// 120: start navigation data (empty).
    StartNavData,
    /// 121: stop navigation data (empty).
    StopNavData,
    /// 122: set navigation threshold, in tenths of a dB.
    SetNavThreshold {
        /// Threshold in dB x 10.
        threshold_db_x10: u16,
    },
    /// 123: navigation data.
    NavigationData(NavigationData),
    /// 140: start non-contoured FFT data (empty).
    StartNonContourFftData,
    /// Any other id: kept whole so it can be skipped (or relayed) without breaking the
    /// stream. Encoding an `Unknown` with a known id writes it raw (for fault injection).
    Unknown {
        /// The message id.
        id: u8,
        /// The payload as received.
        payload: Bytes,
    },
}

/// Requires an empty payload for a header-only message.
fn empty(payload: &Bytes, msg: Message) -> Result<Message, PayloadError> {
    if payload.is_empty() {
        Ok(msg)
    } else {
        Err(PayloadError::WrongLength {
            expected: 0,
            got: payload.len(),
        })
    }
}

impl Message {
    /// The id this message has on the wire.
    pub fn id(&self) -> u8 {
        use message_id as id;
        match self {
            Message::KeepAlive => id::KEEP_ALIVE,
            Message::Configuration(_) => id::CONFIGURATION,
            Message::ConfigurationRequest => id::CONFIGURATION_REQUEST,
            Message::StartFftData => id::START_FFT_DATA,
            Message::StopFftData => id::STOP_FFT_DATA,
            Message::StartHealthMsgs => id::START_HEALTH_MSGS,
            Message::StopHealthMsgs => id::STOP_HEALTH_MSGS,
            Message::ResetRfHealth => id::RESET_RF_HEALTH,
            Message::FftData(fft) => fft.width.message_id(),
            Message::Health(_) => id::HEALTH,
            Message::ContourUpdate(_) => id::CONTOUR_UPDATE,
            Message::SectorBlankingUpdate(_) => id::SECTOR_BLANKING_UPDATE,
            Message::SystemRestart => id::SYSTEM_RESTART,
            Message::StartNavData => id::START_NAV_DATA,
            Message::StopNavData => id::STOP_NAV_DATA,
            Message::SetNavThreshold { .. } => id::SET_NAV_THRESHOLD,
            Message::NavigationData(_) => id::NAVIGATION_DATA,
            Message::StartNonContourFftData => id::START_NON_CONTOUR_FFT_DATA,
            Message::Unknown { id, .. } => *id,
        }
    }

    /// Decodes the payload of a message with id `id`. Bins, health and unknown payloads
    /// are slices of `payload`, not copies. Unknown ids decode to [`Message::Unknown`].
    pub fn decode_payload(id: u8, payload: Bytes) -> Result<Message, PayloadError> {
        use message_id as mid;
        match id {
            mid::KEEP_ALIVE => empty(&payload, Message::KeepAlive),
            mid::CONFIGURATION => {
                Configuration::decode(&payload).map(|c| Message::Configuration(Box::new(c)))
            }
            mid::CONFIGURATION_REQUEST => empty(&payload, Message::ConfigurationRequest),
            mid::START_FFT_DATA => empty(&payload, Message::StartFftData),
            mid::STOP_FFT_DATA => empty(&payload, Message::StopFftData),
            mid::START_HEALTH_MSGS => empty(&payload, Message::StartHealthMsgs),
            mid::STOP_HEALTH_MSGS => empty(&payload, Message::StopHealthMsgs),
            mid::RESET_RF_HEALTH => empty(&payload, Message::ResetRfHealth),
            mid::FFT_DATA => FftData::decode(&payload, BinWidth::Eight).map(Message::FftData),
            mid::HIGH_PRECISION_FFT_DATA => {
                FftData::decode(&payload, BinWidth::Sixteen).map(Message::FftData)
            }
            mid::HEALTH => Ok(Message::Health(payload)),
            mid::CONTOUR_UPDATE => ContourUpdate::decode(&payload).map(Message::ContourUpdate),
            mid::SECTOR_BLANKING_UPDATE => {
                SectorBlanking::decode(&payload).map(Message::SectorBlankingUpdate)
            }
            mid::SYSTEM_RESTART => empty(&payload, Message::SystemRestart),
            mid::START_NAV_DATA => empty(&payload, Message::StartNavData),
            mid::STOP_NAV_DATA => empty(&payload, Message::StopNavData),
            mid::SET_NAV_THRESHOLD => match *payload {
                [hi, lo] => Ok(Message::SetNavThreshold {
                    threshold_db_x10: u16::from_be_bytes([hi, lo]),
                }),
                _ => Err(PayloadError::WrongLength {
                    expected: 2,
                    got: payload.len(),
                }),
            },
            mid::NAVIGATION_DATA => NavigationData::decode(&payload).map(Message::NavigationData),
            mid::START_NON_CONTOUR_FFT_DATA => empty(&payload, Message::StartNonContourFftData),
            id => Ok(Message::Unknown { id, payload }),
        }
    }

    /// Payload length when encoded.
    pub fn encoded_payload_len(&self) -> usize {
        match self {
            Message::Configuration(c) => c.encoded_payload_len(),
            Message::FftData(f) => f.encoded_payload_len(),
            Message::Health(p) | Message::Unknown { payload: p, .. } => p.len(),
            Message::ContourUpdate(c) => c.encoded_payload_len(),
            Message::SectorBlankingUpdate(s) => s.encoded_payload_len(),
            Message::SetNavThreshold { .. } => 2,
            Message::NavigationData(n) => n.encoded_payload_len(),
            Message::KeepAlive
            | Message::ConfigurationRequest
            | Message::StartFftData
            | Message::StopFftData
            | Message::StartHealthMsgs
            | Message::StopHealthMsgs
            | Message::ResetRfHealth
            | Message::SystemRestart
            | Message::StartNavData
            | Message::StopNavData
            | Message::StartNonContourFftData => 0,
        }
    }

    /// Whole frame length when encoded, header included.
    pub fn encoded_len(&self) -> usize {
        HEADER_LEN + self.encoded_payload_len()
    }

    /// Appends this message as one whole frame (header and payload) to `dst`.
    ///
    /// Fails, writing nothing, when the payload would reach 1,000,000 bytes, 16-bit bins
    /// are an odd number of bytes, an FFT data offset is below 14, or there are more than
    /// 255 blanking sectors.
    pub fn encode(&self, dst: &mut BytesMut) -> Result<(), EncodeError> {
        let id = self.id();
        let payload_len = self.encoded_payload_len();
        checked_payload_size(id, payload_len)?;
        let sector_count = match self {
            Message::FftData(f) => {
                f.validate_for_encoding()?;
                0
            }
            Message::SectorBlankingUpdate(s) => s.validate_for_encoding()?,
            _ => 0,
        };
        dst.reserve(HEADER_LEN + payload_len);
        encode_header(dst, id, payload_len)?;
        match self {
            Message::Configuration(c) => c.encode_payload(dst),
            Message::FftData(f) => f.encode_payload(dst),
            Message::Health(p) | Message::Unknown { payload: p, .. } => dst.put_slice(p),
            Message::ContourUpdate(c) => c.encode_payload(dst),
            Message::SectorBlankingUpdate(s) => s.encode_payload(sector_count, dst),
            Message::SetNavThreshold { threshold_db_x10 } => dst.put_u16(*threshold_db_x10),
            Message::NavigationData(n) => n.encode_payload(dst),
            Message::KeepAlive
            | Message::ConfigurationRequest
            | Message::StartFftData
            | Message::StopFftData
            | Message::StartHealthMsgs
            | Message::StopHealthMsgs
            | Message::ResetRfHealth
            | Message::SystemRestart
            | Message::StartNavData
            | Message::StopNavData
            | Message::StartNonContourFftData => {}
        }
        Ok(())
    }

    /// Encodes into a fresh buffer.
    pub fn to_bytes(&self) -> Result<Bytes, EncodeError> {
        let mut dst = BytesMut::with_capacity(self.encoded_len());
        self.encode(&mut dst)?;
        Ok(dst.freeze())
    }
}
