//! The fault model: why a frame has no distance ([`Fault`], each with a short kind that the
//! diagnostics and the counts name), and the errors of the inputs that are not frames
//! ([`InputError`]: the message is dropped, the stream goes on). A fault is reported with its
//! reason at ERROR and never as a distance (docs/safety.md, "The fault model").

use crate::cloud::CloudError;
use crate::msg::MsgError;
use crate::query::QueryError;
use crate::tf::{JointError, TfError};

/// Why a frame has no distance.
#[derive(Debug, thiserror::Error)]
pub enum Fault {
    #[error("decode error: {0}")]
    Decode(#[from] CloudError),
    #[error("missing joint state: {0}")]
    Joints(#[from] JointError),
    #[error("missing transform: {0}")]
    Tf(#[from] TfError),
    #[error("query failed: {0}")]
    Query(#[from] QueryError),
    #[error("cloud has no frame_id")]
    NoFrame,
    /// A depth image whose source has no usable CameraInfo: none received yet on `topic`, or
    /// the last one refused (`reason`).
    #[error("depth image without camera model: {reason} (CameraInfo topic {topic})")]
    NoCameraInfo { topic: String, reason: String },
    /// A stamp of 0: the driver never set it, so the cloud cannot be placed in time.
    #[error("cloud stamp is 0 (not set by its publisher)")]
    NoStamp,
    /// Older than the source's `source_timeout` by the clock (the node's, or the bag's log
    /// time in replay): the scene may have changed since.
    #[error("stale cloud: stamped {age_s:.3} s before now (source_timeout {timeout_s} s)")]
    StaleCloud { age_s: f64, timeout_s: f64 },
    /// Ahead of the clock by more than `future_stamp_tolerance`: a wrong clock on one side,
    /// so neither the stamp nor the transforms looked up at it can be trusted.
    #[error(
        "cloud from the future: stamped {ahead_s:.3} s after now \
         (future_stamp_tolerance {tolerance_s} s)"
    )]
    FutureCloud { ahead_s: f64, tolerance_s: f64 },
    /// Every point NaN, infinite, (0, 0, 0) or outside the source's range: a blinded or
    /// covered sensor. Nothing is known about the scene, so this is a fault, never "clear".
    #[error("no valid points in the cloud ({total} points)")]
    NoValidPoints { total: u64 },
    /// An exclusion volume whose frame has no transform at the cloud's stamp.
    #[error("exclusion volume {volume}: {source}")]
    ExclusionFrame { volume: String, source: TfError },
    /// The node's clock cannot be trusted: with `use_sim_time`, `/clock` silent or not heard
    /// yet (stamps cannot be checked against it).
    #[error("clock: {0}")]
    Clock(String),
    /// More than one writer on the source's topic within `second_publisher_window`: which
    /// one's frame is the scene is unknown, so neither is taken.
    #[error(
        "more than one publisher on {topic}: writers {writers} (second_publisher_window {window_s} s)"
    )]
    SecondPublisher {
        topic: String,
        writers: String,
        window_s: f64,
    },
    /// More than one writer on the source's topic by discovery (DDS SEDP, rmw_zenoh's
    /// liveliness tokens), whatever reaches the node: a writer whose messages are all lost is
    /// still there, so the other's frames are not the scene either.
    #[error(
        "{count} publishers matched on {topic} by discovery: {writers} (one voice per source: \
         ERROR until only one is left)"
    )]
    MatchedWriters {
        topic: String,
        count: usize,
        writers: String,
    },
    #[error("source {source_name}: {what} for {silent_s:.2} s (source_timeout {timeout_s} s)")]
    SourceTimeout {
        source_name: String,
        what: &'static str,
        silent_s: f64,
        timeout_s: f64,
    },
}

impl Fault {
    /// A short key for counting faults by kind.
    pub fn kind(&self) -> &'static str {
        match self {
            Fault::Decode(_) => "decode",
            Fault::Joints(JointError::SecondPublisher { .. }) => "second_publisher",
            Fault::Joints(JointError::Stale { .. }) => "stale_joint_state",
            Fault::Joints(_) => "joint_state",
            Fault::Tf(TfError::SecondPublisher { .. }) => "second_publisher",
            Fault::Tf(TfError::Stale { .. }) => "stale_tf",
            Fault::Tf(_) => "tf",
            Fault::Query(_) => "query",
            Fault::NoFrame => "decode",
            Fault::NoCameraInfo { .. } => "camera_info",
            Fault::NoStamp => "no_stamp",
            Fault::StaleCloud { .. } => "stale_cloud",
            Fault::FutureCloud { .. } => "future_cloud",
            Fault::NoValidPoints { .. } => "no_valid_points",
            Fault::SourceTimeout { .. } => "stale_source",
            Fault::Clock(_) => "clock",
            Fault::ExclusionFrame { .. } => "exclusion_tf",
            Fault::SecondPublisher { .. } | Fault::MatchedWriters { .. } => "second_publisher",
        }
    }
}

/// Errors of the TF and joint-state inputs themselves (the message is dropped).
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{topic}: {source}")]
    Msg { topic: String, source: MsgError },
    #[error("{topic}: {source}")]
    Tf { topic: String, source: TfError },
    #[error("{topic}: {source}")]
    Joints { topic: String, source: JointError },
    #[error("{topic}: {source}")]
    Camera {
        topic: String,
        source: Box<CloudError>,
    },
}
