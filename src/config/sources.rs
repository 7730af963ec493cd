//! The point cloud sources of a config (`sources` and each `<source>.x`): what each publishes
//! (a cloud or a depth image with its CameraInfo), on which topic and QoS, its range limits and
//! its timeout; and the stray-point filter applied to every source's points.

use super::choices::{SourceKind, SourceQos};
use super::entries::names;
use super::error::ConfigError;
use super::values::Values;

/// A point cloud source.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceConfig {
    pub name: String,
    pub kind: SourceKind,
    pub topic: String,
    /// The CameraInfo topic of a depth image source.
    pub camera_info_topic: Option<String>,
    pub enabled: bool,
    pub source_timeout_s: f64,
    pub min_range_m: f64,
    pub max_range_m: Option<f64>,
    pub reliable: bool,
    /// A return at range r shows its ray free up to r − this (m; unobserved space).
    pub range_noise_m: f64,
}

/// The stray-point filter: a source's nearest point counts only with at least `min_points`
/// valid points (itself included) within `cluster_radius_m` of it (`monitor`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrayFilter {
    pub min_points: u32,
    pub cluster_radius_m: f64,
    /// At most this many points rejected per frame.
    pub max_rejected: u32,
}

impl StrayFilter {
    pub fn enabled(&self) -> bool {
        self.min_points > 1
    }

    /// `stray_filter.*`.
    pub(super) fn read(v: &Values) -> Result<Self, ConfigError> {
        Ok(StrayFilter {
            min_points: v.count("stray_filter.min_points")?,
            cluster_radius_m: v
                .distance("stray_filter.cluster_radius", "stray_filter.cluster_radius")?,
            max_rejected: v.count("stray_filter.max_rejected")?,
        })
    }
}

/// The CameraInfo topic image_transport pairs with an image topic: `camera_info` in the image
/// topic's namespace (`/camera/depth/image_raw` → `/camera/depth/camera_info`).
pub fn camera_info_beside(image_topic: &str) -> String {
    match image_topic.rsplit_once('/') {
        Some((ns, _)) => format!("{ns}/camera_info"),
        None => "camera_info".into(),
    }
}

/// The sources named in `sources`.
pub(super) fn sources(v: &Values, names: &[String]) -> Result<Vec<SourceConfig>, ConfigError> {
    names.iter().map(|s| source(v, s)).collect()
}

/// Source `s`'s parameters.
fn source(v: &Values, s: &str) -> Result<SourceConfig, ConfigError> {
    let get = |rest: &str| names(s, "<source>", rest);
    let (topic, t) = get("topic");
    let (enabled, e) = get("enabled");
    let (timeout, to) = get("source_timeout");
    let (min, mi) = get("min_range");
    let (max, ma) = get("max_range");
    let (qos, q) = get("qos");
    let (kind, k) = get("type");
    let (info, i) = get("camera_info_topic");
    let (noise, n) = get("range_noise");
    let kind: SourceKind = v.choice(&kind, &k)?;
    let topic = v.string(&topic, &t)?;
    let camera_info_topic = match kind {
        SourceKind::PointCloud => None,
        SourceKind::DepthImage => Some(
            v.opt_string(&info, &i)?
                .unwrap_or_else(|| camera_info_beside(&topic)),
        ),
    };
    let reliable = v.choice::<SourceQos>(&qos, &q)? == SourceQos::Reliable;
    let max_range_m = v.opt_f64(&max, &ma)?;
    if max_range_m.is_some_and(|m| m <= 0.0 || m.is_nan()) {
        return Err(Values::bad(&max, "must be > 0"));
    }
    let source_timeout_s = v.distance(&timeout, &to)?;
    if source_timeout_s <= 0.0 {
        return Err(Values::bad(&timeout, "must be > 0"));
    }
    Ok(SourceConfig {
        name: s.to_owned(),
        kind,
        topic,
        camera_info_topic,
        enabled: v.bool(&enabled, &e)?,
        source_timeout_s,
        min_range_m: v.distance(&min, &mi)?,
        max_range_m,
        reliable,
        range_noise_m: v.distance(&noise, &n)?,
    })
}
