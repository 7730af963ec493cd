//! `builtin_interfaces`, `std_msgs`, `rosgraph_msgs/Clock` and the `rcl_interfaces` messages
//! a node publishes (`Log`, `ParameterEvent`).

use serde::{Deserialize, Serialize};

use super::message::ros_message;

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}
ros_message!(
    Time,
    "builtin_interfaces/msg/Time",
    "int32 sec\nuint32 nanosec\n"
);

impl Time {
    /// The system clock, in nanoseconds since the epoch (0 for a clock set before 1970).
    pub fn now_nanos() -> i64 {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64)
    }
    /// Nanoseconds since the epoch.
    pub fn as_nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
    /// The time `ns` nanoseconds since the epoch (floor division, so negative times work).
    pub fn from_nanos(ns: i64) -> Self {
        Self {
            sec: ns.div_euclid(1_000_000_000) as i32,
            nanosec: ns.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// `builtin_interfaces/msg/Duration`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    pub sec: i32,
    pub nanosec: u32,
}
ros_message!(
    Duration,
    "builtin_interfaces/msg/Duration",
    "int32 sec\nuint32 nanosec\n"
);

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}
ros_message!(
    Header,
    "std_msgs/msg/Header",
    "builtin_interfaces/Time stamp\nstring frame_id\n"
);

/// `std_msgs/msg/Float64`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Float64 {
    pub data: f64,
}
ros_message!(Float64, "std_msgs/msg/Float64", "float64 data\n");

/// `rosgraph_msgs/msg/Clock`: the simulated time on `/clock` (a simulator, `ros2 bag play
/// --clock`), which nodes with `use_sim_time` take as their clock.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Clock {
    pub clock: Time,
}
ros_message!(
    Clock,
    "rosgraph_msgs/msg/Clock",
    "builtin_interfaces/Time clock\n"
);

/// `rcl_interfaces/msg/Log`: a line of a node's log on `/rosout` (`level` one of the constants).
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Log {
    pub stamp: Time,
    pub level: u8,
    pub name: String,
    pub msg: String,
    pub file: String,
    pub function: String,
    pub line: u32,
}
ros_message!(
    Log,
    "rcl_interfaces/msg/Log",
    "uint8 DEBUG=10\nuint8 INFO=20\nuint8 WARN=30\nuint8 ERROR=40\nuint8 FATAL=50\nbuiltin_interfaces/Time stamp\nuint8 level\nstring name\nstring msg\nstring file\nstring function\nuint32 line\n"
);

impl Log {
    pub const DEBUG: u8 = 10;
    pub const INFO: u8 = 20;
    pub const WARN: u8 = 30;
    pub const ERROR: u8 = 40;
}

/// `rcl_interfaces/msg/ParameterValue`: one value; `kind` (the field `type`) says which field
/// holds it, as `rcl_interfaces/msg/ParameterType` numbers them (0 not set, 1 bool, 2 integer,
/// 3 double, 4 string, 5 bytes, 6–9 the bool, integer, double and string arrays).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ParameterValue {
    #[serde(rename = "type")]
    pub kind: u8,
    pub bool_value: bool,
    pub integer_value: i64,
    pub double_value: f64,
    pub string_value: String,
    pub byte_array_value: Vec<u8>,
    pub bool_array_value: Vec<bool>,
    pub integer_array_value: Vec<i64>,
    pub double_array_value: Vec<f64>,
    pub string_array_value: Vec<String>,
}
ros_message!(
    ParameterValue,
    "rcl_interfaces/msg/ParameterValue",
    "uint8 type\nbool bool_value\nint64 integer_value\nfloat64 double_value\nstring string_value\nbyte[] byte_array_value\nbool[] bool_array_value\nint64[] integer_array_value\nfloat64[] double_array_value\nstring[] string_array_value\n"
);

/// `rcl_interfaces/msg/Parameter`: a named value.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Parameter {
    pub name: String,
    pub value: ParameterValue,
}
ros_message!(
    Parameter,
    "rcl_interfaces/msg/Parameter",
    "string name\nParameterValue value\n"
);

/// `rcl_interfaces/msg/ParameterEvent`: what one change did to node `node`'s parameters
/// (`/parameter_events`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ParameterEvent {
    pub stamp: Time,
    pub node: String,
    pub new_parameters: Vec<Parameter>,
    pub changed_parameters: Vec<Parameter>,
    pub deleted_parameters: Vec<Parameter>,
}
ros_message!(
    ParameterEvent,
    "rcl_interfaces/msg/ParameterEvent",
    "builtin_interfaces/Time stamp\nstring node\nParameter[] new_parameters\nParameter[] changed_parameters\nParameter[] deleted_parameters\n"
);

/// `std_msgs/msg/String` (`/robot_description`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StringMessage {
    pub data: String,
}
ros_message!(StringMessage, "std_msgs/msg/String", "string data\n");

/// `std_msgs/msg/Bool`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Bool {
    pub data: bool,
}
ros_message!(Bool, "std_msgs/msg/Bool", "bool data\n");

/// `std_msgs/msg/ColorRGBA`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRgba {
    pub r: f32,
    pub g: f32,
    pub b: f32,
    pub a: f32,
}
ros_message!(
    ColorRgba,
    "std_msgs/msg/ColorRGBA",
    "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n"
);
