//! The configuration message's protobuf tail, `ConfigurationData` (proto2), as hand-written
//! prost structs: no build script, no protoc. Field numbers and types follow Navtech's
//! `configurationdata.proto` and `radarmodel.proto`. Fields we do not know are skipped
//! on decode (prost's default); nested messages we do not interpret (software versions,
//! NVRAM contents) are kept as opaque bytes, which is wire-compatible with a message.

use bytes::Bytes;

/// Flags in [`ConfigurationData::radarfeatures`].
pub mod radar_features {
    /// The radar can autotune.
    pub const AUTOTUNE: i32 = 1;
    /// A secondary processing module is present.
    pub const SECONDARY_PROCESSING: i32 = 2;
    /// The radar can send non-contoured data (message 140).
    pub const NON_CONTOURED_DATA: i32 = 4;
}

/// `RadarModel`: which unit this is.
#[derive(Clone, PartialEq, prost::Message)]
pub struct RadarModel {
    /// Model id.
    #[prost(uint32, optional, tag = "1")]
    pub id: Option<u32>,
    /// Model name, e.g. "CTS350-X".
    #[prost(string, optional, tag = "2")]
    pub name: Option<String>,
    /// Model unique id.
    #[prost(string, optional, tag = "3")]
    pub uniqueid: Option<String>,
    /// Instrumented range in metres.
    #[prost(float, optional, tag = "4")]
    pub rangeinmetres: Option<f32>,
    /// Profile id.
    #[prost(string, optional, tag = "5")]
    pub profileid: Option<String>,
}

/// `ConfigurationData`: the protobuf tail of a configuration message (section 3.1).
#[derive(Clone, PartialEq, prost::Message)]
pub struct ConfigurationData {
    /// 1: the radar model.
    #[prost(message, optional, tag = "1")]
    pub model: Option<RadarModel>,
    /// 2: MAC address.
    #[prost(string, optional, tag = "2")]
    pub macaddress: Option<String>,
    /// 3: `SoftwareVersions` message, kept opaque.
    #[prost(bytes = "bytes", optional, tag = "3")]
    pub softwareversions: Option<Bytes>,
    /// 4: `NVRamContents` message, kept opaque.
    #[prost(bytes = "bytes", optional, tag = "4")]
    pub nvramcontents: Option<Bytes>,
    /// 5: range resolution in hertz.
    #[prost(float, optional, tag = "5")]
    pub rangeresolutionhz: Option<f32>,
    /// 6: module serial number.
    #[prost(string, optional, tag = "6")]
    pub moduleserialnumber: Option<String>,
    /// 7: autotune value.
    #[prost(int32, optional, tag = "7")]
    pub autotunevalue: Option<i32>,
    /// 8: radar unique id.
    #[prost(string, optional, tag = "8")]
    pub radaruniqueid: Option<String>,
    /// 9: bits per bin, 8 or 16; absent means 8.
    #[prost(int32, optional, tag = "9")]
    pub datawidth: Option<i32>,
    /// 10: range resolution in metres per bin.
    #[prost(float, optional, tag = "10")]
    pub rangeresolutionmetres: Option<f32>,
    /// 11: feature flags (see [`radar_features`]); an enum on the wire, read as a varint.
    #[prost(int32, optional, tag = "11")]
    pub radarfeatures: Option<i32>,
    /// 12: staring mode.
    #[prost(int32, optional, tag = "12")]
    pub staringmode: Option<i32>,
    /// 13: onboard MAC address.
    #[prost(string, optional, tag = "13")]
    pub onboardmacaddress: Option<String>,
}

impl ConfigurationData {
    /// The smallest tail Navtech's own client accepts: data width and range resolution.
    pub fn minimal(data_width_bits: i32, range_resolution_m: f32) -> Self {
        Self {
            datawidth: Some(data_width_bits),
            rangeresolutionmetres: Some(range_resolution_m),
            ..Self::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use prost::Message as _;

    #[test]
    fn a_tail_with_only_data_width_and_resolution_has_the_expected_bytes() {
        let tail = ConfigurationData::minimal(16, 0.0438).encode_to_vec();
        let mut expected = vec![0x48, 16, 0x55];
        expected.extend_from_slice(&0.0438f32.to_le_bytes());
        assert_eq!(tail, expected);
    }

    #[test]
    fn unknown_fields_are_skipped() {
        // field 99 varint 7, then field 9 varint 16.
        let bytes = [0x98, 0x06, 0x07, 0x48, 0x10];
        let data = ConfigurationData::decode(&bytes[..]).unwrap();
        assert_eq!(data.datawidth, Some(16));
    }
}
