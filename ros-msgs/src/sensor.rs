//! `sensor_msgs`: PointField, PointCloud2, Image, CompressedImage.

use serde::{Deserialize, Serialize};

use crate::schema::{MsgDef, RosMessage};
use crate::std_msgs::{Header, HEADER};

/// `sensor_msgs/PointField`: one field of a point cloud's points.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PointField {
    /// Field name (`x`, `y`, `intensity`...).
    pub name: String,
    /// Byte offset inside a point.
    pub offset: u32,
    /// One of the datatype constants.
    pub datatype: u8,
    /// Elements in the field.
    pub count: u32,
}

impl PointField {
    /// `INT8`.
    pub const INT8: u8 = 1;
    /// `UINT8`.
    pub const UINT8: u8 = 2;
    /// `INT16`.
    pub const INT16: u8 = 3;
    /// `UINT16`.
    pub const UINT16: u8 = 4;
    /// `INT32`.
    pub const INT32: u8 = 5;
    /// `UINT32`.
    pub const UINT32: u8 = 6;
    /// `FLOAT32`.
    pub const FLOAT32: u8 = 7;
    /// `FLOAT64`.
    pub const FLOAT64: u8 = 8;

    /// A single float32 field at `offset`.
    pub fn float32(name: &str, offset: u32) -> Self {
        Self {
            name: name.to_string(),
            offset,
            datatype: Self::FLOAT32,
            count: 1,
        }
    }
}

/// Definition of [`PointField`].
pub static POINT_FIELD: MsgDef = MsgDef {
    name: "sensor_msgs/PointField",
    text: "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\nuint8 UINT16  = 4\nuint8 INT32   = 5\nuint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\nstring name\nuint32 offset\nuint8  datatype\nuint32 count\n",
    uses: &[],
};

impl RosMessage for PointField {
    const DEF: &'static MsgDef = &POINT_FIELD;
}

/// `sensor_msgs/PointCloud2`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    /// Time and frame.
    pub header: Header,
    /// Rows (1 for an unordered cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The points' fields.
    pub fields: Vec<PointField>,
    /// Byte order of `data`.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// No invalid points.
    pub is_dense: bool,
}

/// Definition of [`PointCloud2`].
pub static POINT_CLOUD2: MsgDef = MsgDef {
    name: "sensor_msgs/PointCloud2",
    text: "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool    is_bigendian\nuint32  point_step\nuint32  row_step\nuint8[] data\nbool is_dense\n",
    uses: &[&HEADER, &POINT_FIELD],
};

impl RosMessage for PointCloud2 {
    const DEF: &'static MsgDef = &POINT_CLOUD2;
}

impl PointCloud2 {
    /// An unordered, little-endian cloud of float32 fields named `names`, one row of
    /// `points` (each as long as `names`; a shorter point is padded with NaN).
    pub fn from_f32_points(header: Header, names: &[&str], points: &[Vec<f32>]) -> Self {
        let fields: Vec<PointField> = names
            .iter()
            .zip((0u32..).step_by(4))
            .map(|(n, off)| PointField::float32(n, off))
            .collect();
        let point_step = 4 * u32::try_from(names.len()).unwrap_or(0);
        let mut data = Vec::with_capacity(points.len() * names.len() * 4);
        for p in points {
            for k in 0..names.len() {
                data.extend_from_slice(&p.get(k).copied().unwrap_or(f32::NAN).to_le_bytes());
            }
        }
        let width = u32::try_from(points.len()).unwrap_or(u32::MAX);
        Self {
            header,
            height: 1,
            width,
            fields,
            is_bigendian: false,
            point_step,
            row_step: point_step.saturating_mul(width),
            data,
            is_dense: true,
        }
    }

    /// The float32 fields of each point, in `fields` order; `None` when the cloud's layout
    /// is not float32 little-endian fields inside `point_step`, or `data` is short.
    pub fn f32_points(&self) -> Option<Vec<Vec<f32>>> {
        if self.is_bigendian
            || self
                .fields
                .iter()
                .any(|f| f.datatype != PointField::FLOAT32)
        {
            return None;
        }
        let step = usize::try_from(self.point_step).ok()?;
        let n = usize::try_from(self.width)
            .ok()?
            .checked_mul(usize::try_from(self.height).ok()?)?;
        if step == 0 || self.data.len() < n.checked_mul(step)? {
            return None;
        }
        let mut out = Vec::with_capacity(n);
        for i in 0..n {
            let mut p = Vec::with_capacity(self.fields.len());
            for f in &self.fields {
                let at = i * step + usize::try_from(f.offset).ok()?;
                let bytes: [u8; 4] = self.data.get(at..at + 4)?.try_into().ok()?;
                p.push(f32::from_le_bytes(bytes));
            }
            out.push(p);
        }
        Some(out)
    }
}

/// `sensor_msgs/Image`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Time and frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`mono8`, `8UC1`...).
    pub encoding: String,
    /// Byte order of multi-byte pixels.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// Rows of pixels.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// Definition of [`Image`].
pub static IMAGE: MsgDef = MsgDef {
    name: "sensor_msgs/Image",
    text: "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data\n",
    uses: &[&HEADER],
};

impl RosMessage for Image {
    const DEF: &'static MsgDef = &IMAGE;
}

/// `sensor_msgs/CompressedImage` (used by `Marker.texture`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Time and frame.
    pub header: Header,
    /// `jpeg`, `png`...
    pub format: String,
    /// The compressed image.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// Definition of [`CompressedImage`].
pub static COMPRESSED_IMAGE: MsgDef = MsgDef {
    name: "sensor_msgs/CompressedImage",
    text: "std_msgs/Header header\nstring format\nuint8[] data\n",
    uses: &[&HEADER],
};

impl RosMessage for CompressedImage {
    const DEF: &'static MsgDef = &COMPRESSED_IMAGE;
}
