//! `visualization_msgs`: Marker and MarkerArray (ROS 2 Humble and later layout: with
//! `texture_resource`, `texture`, `uv_coordinates`, `mesh_file`).

use serde::{Deserialize, Serialize};

use crate::builtin::{Duration, DURATION};
use crate::geometry::{Point, Pose, Vector3, POINT, POSE, VECTOR3};
use crate::schema::{MsgDef, RosMessage};
use crate::sensor::{CompressedImage, COMPRESSED_IMAGE};
use crate::std_msgs::{ColorRGBA, Header, COLOR_RGBA, HEADER};

/// `visualization_msgs/UVCoordinate`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UVCoordinate {
    /// u in [0, 1].
    pub u: f32,
    /// v in [0, 1].
    pub v: f32,
}

/// Definition of [`UVCoordinate`].
pub static UV_COORDINATE: MsgDef = MsgDef {
    name: "visualization_msgs/UVCoordinate",
    text: "float32 u\nfloat32 v\n",
    uses: &[],
};

impl RosMessage for UVCoordinate {
    const DEF: &'static MsgDef = &UV_COORDINATE;
}

/// `visualization_msgs/MeshFile`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// File name.
    pub filename: String,
    /// The file's bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// Definition of [`MeshFile`].
pub static MESH_FILE: MsgDef = MsgDef {
    name: "visualization_msgs/MeshFile",
    text: "string filename\nuint8[] data\n",
    uses: &[],
};

impl RosMessage for MeshFile {
    const DEF: &'static MsgDef = &MESH_FILE;
}

/// `visualization_msgs/Marker`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Time and frame.
    pub header: Header,
    /// Namespace.
    pub ns: String,
    /// Id inside the namespace.
    pub id: i32,
    /// Shape (`Marker::CYLINDER`...).
    #[serde(rename = "type")]
    pub type_: i32,
    /// `ADD`, `DELETE`, `DELETEALL`.
    pub action: i32,
    /// Pose in the frame.
    pub pose: Pose,
    /// Size, metres.
    pub scale: Vector3,
    /// Colour.
    pub color: ColorRGBA,
    /// 0: forever.
    pub lifetime: Duration,
    /// Re-transformed every frame.
    pub frame_locked: bool,
    /// Points (line strips, point lists...).
    pub points: Vec<Point>,
    /// Per-point colours.
    pub colors: Vec<ColorRGBA>,
    /// Texture URI.
    pub texture_resource: String,
    /// Embedded texture.
    pub texture: CompressedImage,
    /// Texture coordinates.
    pub uv_coordinates: Vec<UVCoordinate>,
    /// Text markers' text.
    pub text: String,
    /// Mesh URI.
    pub mesh_resource: String,
    /// Embedded mesh.
    pub mesh_file: MeshFile,
    /// Use the mesh's materials.
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// `ARROW`.
    pub const ARROW: i32 = 0;
    /// `CUBE`.
    pub const CUBE: i32 = 1;
    /// `SPHERE`.
    pub const SPHERE: i32 = 2;
    /// `CYLINDER`.
    pub const CYLINDER: i32 = 3;
    /// `LINE_STRIP`.
    pub const LINE_STRIP: i32 = 4;
    /// `ADD` (and `MODIFY`).
    pub const ADD: i32 = 0;
    /// `DELETE`.
    pub const DELETE: i32 = 2;
    /// `DELETEALL`.
    pub const DELETEALL: i32 = 3;
}

/// Definition of [`Marker`].
pub static MARKER: MsgDef = MsgDef {
    name: "visualization_msgs/Marker",
    text: "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\nint32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\nint32 DELETEALL=3\nstd_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\nsensor_msgs/CompressedImage texture\nUVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\nMeshFile mesh_file\nbool mesh_use_embedded_materials\n",
    uses: &[
        &HEADER,
        &POSE,
        &VECTOR3,
        &COLOR_RGBA,
        &DURATION,
        &POINT,
        &COMPRESSED_IMAGE,
        &UV_COORDINATE,
        &MESH_FILE,
    ],
};

impl RosMessage for Marker {
    const DEF: &'static MsgDef = &MARKER;
}

/// `visualization_msgs/MarkerArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}

/// Definition of [`MarkerArray`].
pub static MARKER_ARRAY: MsgDef = MsgDef {
    name: "visualization_msgs/MarkerArray",
    text: "Marker[] markers\n",
    uses: &[&MARKER],
};

impl RosMessage for MarkerArray {
    const DEF: &'static MsgDef = &MARKER_ARRAY;
}
