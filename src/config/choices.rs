//! The enums the parameters name one value of, beyond those of the areas below (`mode` and
//! `backend` are the query's): what a source is and how it is subscribed to, and what shape an
//! exclusion volume or attached object has. Each is a [`Choice`], declared with its parameter
//! (`params::one_of`) and read through that declaration (`Values::choice`).

use crate::choice::Choice;

/// What a source publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceKind {
    /// `sensor_msgs/PointCloud2`.
    PointCloud,
    /// `sensor_msgs/Image` depth images with their `sensor_msgs/CameraInfo`.
    DepthImage,
}

impl Choice for SourceKind {
    const ALL: &'static [Self] = &[SourceKind::PointCloud, SourceKind::DepthImage];
    fn name(self) -> &'static str {
        match self {
            SourceKind::PointCloud => "pointcloud",
            SourceKind::DepthImage => "depth_image",
        }
    }
}

/// A source's QoS (`<source>.qos`): best effort, as sensors publish, or reliable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum SourceQos {
    SensorData,
    Reliable,
}

impl Choice for SourceQos {
    const ALL: &'static [Self] = &[SourceQos::SensorData, SourceQos::Reliable];
    fn name(self) -> &'static str {
        match self {
            SourceQos::SensorData => "sensor_data",
            SourceQos::Reliable => "reliable",
        }
    }
}

/// What `shape` names: a primitive as URDF gives one, or a mesh file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum ShapeKind {
    Box,
    Sphere,
    Cylinder,
    Mesh,
}

impl Choice for ShapeKind {
    const ALL: &'static [Self] = &[
        ShapeKind::Box,
        ShapeKind::Sphere,
        ShapeKind::Cylinder,
        ShapeKind::Mesh,
    ];
    fn name(self) -> &'static str {
        match self {
            ShapeKind::Box => "box",
            ShapeKind::Sphere => "sphere",
            ShapeKind::Cylinder => "cylinder",
            ShapeKind::Mesh => "mesh",
        }
    }
}

/// What the monitor does with the space no source has seen free (`unobserved`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UnobservedPolicy {
    /// Not computed.
    Ignore,
    /// Computed and published; the levels are the seen distance's.
    Report,
    /// The level, the stop and the speed-scaling factor take the smaller of the two distances.
    Protect,
}

impl Choice for UnobservedPolicy {
    const ALL: &'static [Self] = &[
        UnobservedPolicy::Ignore,
        UnobservedPolicy::Report,
        UnobservedPolicy::Protect,
    ];
    fn name(self) -> &'static str {
        match self {
            UnobservedPolicy::Ignore => "ignore",
            UnobservedPolicy::Report => "report",
            UnobservedPolicy::Protect => "protect",
        }
    }
}

/// What the robot's own shadow counts as (`unobserved_self_shadow`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SelfShadow {
    /// As any unseen space.
    Count,
    /// Reported on its own, left out of the unseen distance.
    Apart,
}

impl Choice for SelfShadow {
    const ALL: &'static [Self] = &[SelfShadow::Count, SelfShadow::Apart];
    fn name(self) -> &'static str {
        match self {
            SelfShadow::Count => "count",
            SelfShadow::Apart => "apart",
        }
    }
}

/// Which parameter changes a running node takes (`parameter_changes`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParameterChanges {
    /// Any valid change; while the safety stop is raised, one that weakens protection is
    /// refused (`Config::weakening`).
    Open,
    /// A change that weakens protection is refused at any time: thresholds may be raised, never
    /// lowered, by anyone on the network.
    StrengthenOnly,
    /// Every change refused: the parameters are those the node started with.
    None,
}

impl Choice for ParameterChanges {
    const ALL: &'static [Self] = &[
        ParameterChanges::Open,
        ParameterChanges::StrengthenOnly,
        ParameterChanges::None,
    ];
    fn name(self) -> &'static str {
        match self {
            ParameterChanges::Open => "open",
            ParameterChanges::StrengthenOnly => "strengthen_only",
            ParameterChanges::None => "none",
        }
    }
}
