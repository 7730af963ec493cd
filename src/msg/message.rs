//! What makes a struct a ROS 2 message here: its type name and its own `.msg` text, stated once
//! per struct by `ros_message!` beside its fields.

use serde::Serialize;

/// A message type: its ROS 2 name and its own `.msg` text (constants first, then fields).
pub trait RosMessage: Serialize {
    /// `pkg/msg/Type`.
    const TYPE: &'static str;
    /// The `.msg` text without comments, as rosbags prints it.
    const OWN_DEFINITION: &'static str;
}

macro_rules! ros_message {
    ($ty:ty, $name:literal, $definition:literal) => {
        impl $crate::msg::RosMessage for $ty {
            const TYPE: &'static str = $name;
            const OWN_DEFINITION: &'static str = $definition;
        }
    };
}
pub(crate) use ros_message;
