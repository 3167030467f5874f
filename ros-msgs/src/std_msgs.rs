//! `std_msgs`: Header and ColorRGBA.

use serde::{Deserialize, Serialize};

use crate::builtin::{Time, TIME};
use crate::schema::{MsgDef, RosMessage};

/// `std_msgs/Header`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was taken.
    pub stamp: Time,
    /// The frame the data is in.
    pub frame_id: String,
}

/// Definition of [`Header`].
pub static HEADER: MsgDef = MsgDef {
    name: "std_msgs/Header",
    text: "builtin_interfaces/Time stamp\nstring frame_id\n",
    uses: &[&TIME],
};

impl RosMessage for Header {
    const DEF: &'static MsgDef = &HEADER;
}

impl Header {
    /// A header at `stamp` in `frame_id`.
    pub fn new(stamp: Time, frame_id: &str) -> Self {
        Self {
            stamp,
            frame_id: frame_id.to_string(),
        }
    }
}

/// `std_msgs/ColorRGBA`, components in [0, 1].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRGBA {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Alpha.
    pub a: f32,
}

/// Definition of [`ColorRGBA`].
pub static COLOR_RGBA: MsgDef = MsgDef {
    name: "std_msgs/ColorRGBA",
    text: "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n",
    uses: &[],
};

impl RosMessage for ColorRGBA {
    const DEF: &'static MsgDef = &COLOR_RGBA;
}
