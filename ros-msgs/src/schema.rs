//! Message definitions as the `ros2msg` schema encoding of MCAP wants them: the message's
//! own `.msg` text, then every definition it uses (directly or not), each once, after a line
//! of 80 `=` and a `MSG: package/Type` line, as rosbag2 writes them.

use serde::de::DeserializeOwned;
use serde::Serialize;

/// The separator line rosbag2 writes between definitions.
pub const SEPARATOR: &str =
    "================================================================================";

/// One `.msg` definition and the definitions its fields name.
#[derive(Debug)]
pub struct MsgDef {
    /// `package/Type`, as the `MSG:` lines name it.
    pub name: &'static str,
    /// The `.msg` text: fields (and constants) in the definition's order.
    pub text: &'static str,
    /// The definitions its fields use directly.
    pub uses: &'static [&'static MsgDef],
}

impl MsgDef {
    /// `package/msg/Type`: the schema name (and ROS 2 type name) rosbag2 writes.
    pub fn schema_name(&self) -> String {
        match self.name.split_once('/') {
            Some((package, ty)) => format!("{package}/msg/{ty}"),
            None => self.name.to_string(),
        }
    }

    /// The `ros2msg` schema text: this definition, then each one it depends on, once,
    /// depth-first in field order.
    pub fn ros2msg(&self) -> String {
        let mut seen: Vec<&'static str> = vec![self.name];
        let mut order: Vec<&'static MsgDef> = Vec::new();
        collect(self, &mut seen, &mut order);
        let mut out = self.text.trim_end().to_string();
        for def in order {
            out.push('\n');
            out.push_str(SEPARATOR);
            out.push_str("\nMSG: ");
            out.push_str(def.name);
            out.push('\n');
            out.push_str(def.text.trim_end());
        }
        out.push('\n');
        out
    }
}

fn collect(def: &MsgDef, seen: &mut Vec<&'static str>, order: &mut Vec<&'static MsgDef>) {
    for used in def.uses {
        if seen.contains(&used.name) {
            continue;
        }
        seen.push(used.name);
        order.push(used);
        collect(used, seen, order);
    }
}

/// A ROS 2 message type: serde layout in `.msg` field order, and its definition.
pub trait RosMessage: Serialize + DeserializeOwned {
    /// The definition (and through it, the schema text).
    const DEF: &'static MsgDef;

    /// `package/msg/Type`.
    fn type_name() -> String {
        Self::DEF.schema_name()
    }

    /// The `ros2msg` schema text.
    fn schema_text() -> String {
        Self::DEF.ros2msg()
    }
}
