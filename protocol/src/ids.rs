//! The Colossus message ids (a leaf: the messages, the FFT data and the decoder share them).

/// Message ids on the wire.
pub mod message_id {
    /// Keep alive, from the radar, empty.
    pub const KEEP_ALIVE: u8 = 1;
    /// Configuration, from the radar.
    pub const CONFIGURATION: u8 = 10;
    /// Configuration request, to the radar, empty.
    pub const CONFIGURATION_REQUEST: u8 = 20;
    /// Start FFT data, to the radar, empty.
    pub const START_FFT_DATA: u8 = 21;
    /// Stop FFT data, to the radar, empty.
    pub const STOP_FFT_DATA: u8 = 22;
    /// Start health messages, to the radar, empty.
    pub const START_HEALTH_MSGS: u8 = 23;
    /// Stop health messages, to the radar, empty.
    pub const STOP_HEALTH_MSGS: u8 = 24;
    /// Reset RF health, to the radar, empty.
    pub const RESET_RF_HEALTH: u8 = 25;
    /// FFT data with 8-bit bins, from the radar.
    pub const FFT_DATA: u8 = 30;
    /// FFT data with 16-bit bins, from the radar.
    pub const HIGH_PRECISION_FFT_DATA: u8 = 31;
    /// Health (protobuf), from the radar.
    pub const HEALTH: u8 = 40;
    /// Contour update, to the radar.
    pub const CONTOUR_UPDATE: u8 = 50;
    /// Sector blanking update, to the radar.
    pub const SECTOR_BLANKING_UPDATE: u8 = 51;
    /// System restart, to the radar, empty.
    pub const SYSTEM_RESTART: u8 = 76;
    /// Start navigation data, to the radar, empty.
    pub const START_NAV_DATA: u8 = 120;
    /// Stop navigation data, to the radar, empty.
    pub const STOP_NAV_DATA: u8 = 121;
    /// Set navigation threshold, to the radar.
    pub const SET_NAV_THRESHOLD: u8 = 122;
    /// Navigation data, from the radar.
    pub const NAVIGATION_DATA: u8 = 123;
    /// Start non-contoured FFT data, to the radar, empty.
    pub const START_NON_CONTOUR_FFT_DATA: u8 = 140;
}
