//! Configuration: a ROS 2 parameters file (`<node>: ros__parameters: …`, the form `ros2 run
//! --ros-args --params-file` reads), validated into a typed [`Config`]. `replay` and the live
//! node read the same files.
//!
//! Every parameter is declared once in [`PARAMETERS`] with its default, unit and meaning; a file
//! may set only declared ones (a misspelt name is an error that names it). Nested maps are
//! flattened to dotted names as ROS 2 does (`front.topic`). Names with a `<source>.` or
//! `<transform>.` prefix are declared per entry of the `sources` and `static_transforms` lists.
//! `-p name:=value` overrides (value in YAML) are applied after the file. Every value is
//! checked at load, and a bad one is an error that names the parameter.
//!
//! `params`: the declaration table. `values`: the flattened values and their typed, checked
//! accessors. Here: the typed [`Config`] they make.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use yaml_rust2::Yaml;

use crate::cloud::exclusion::ExclusionVolume;
use crate::ist::BuildOptions;
use crate::msg::{Header, Time, TransformStamped};
use crate::query::{Backend, LinkSelection, Mode, QueryOptions};
use crate::robot::{urdf::resolve_uri, AttachedObject, PackagePath};
use crate::separation::{SsmParams, StoppingTable};

mod files;
mod params;
mod runtime;
mod shapes;
mod values;

pub use files::{key_matches, ParameterSources};
pub use params::{default_of, markdown_table, ParamDecl, ParamKind, PARAMETERS};
pub use runtime::Parameter;
use values::{flatten, scalar_yaml, Values};

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: YAML: {message}")]
    Yaml { path: PathBuf, message: String },
    #[error("{path}: no `<node>: ros__parameters:` section")]
    NoParameters { path: PathBuf },
    #[error("parameter {0} is not declared (see `config/README.md`)")]
    Unknown(String),
    #[error("parameter {name}: {message}")]
    Invalid { name: String, message: String },
}

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
}

/// What a source publishes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceKind {
    /// `sensor_msgs/PointCloud2`.
    PointCloud,
    /// `sensor_msgs/Image` depth images with their `sensor_msgs/CameraInfo`.
    DepthImage,
}

/// The CameraInfo topic image_transport pairs with an image topic: `camera_info` in the image
/// topic's namespace (`/camera/depth/image_raw` → `/camera/depth/camera_info`).
pub fn camera_info_beside(image_topic: &str) -> String {
    match image_topic.rsplit_once('/') {
        Some((ns, _)) => format!("{ns}/camera_info"),
        None => "camera_info".into(),
    }
}

/// Where the robot's URDF comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum RobotSource {
    /// A file, or a `package://` URI (resolved by [`Config::robot_source`]).
    File(PathBuf),
    /// The URDF text given as the parameter's value.
    Text(String),
    /// A `std_msgs/String` topic the node reads it from.
    Topic(String),
}

/// The validated configuration.
#[derive(Debug, Clone)]
pub struct Config {
    /// Node name and namespace from the file's top key (`/ns/name`), `ist_monitor` for `/**`.
    pub node_name: String,
    pub namespace: String,
    /// `robot_description`, or `robot_description_topic` when it is not set.
    pub robot_description: Option<RobotSource>,
    pub package_paths: Vec<PackagePath>,
    pub query: QueryOptions,
    pub selection: LinkSelection,
    pub build: BuildOptions,
    pub cache_dir: Option<PathBuf>,
    pub joint_states_topic: String,
    pub tf_tolerance_s: f64,
    pub joint_state_tolerance_s: f64,
    pub future_stamp_tolerance_s: f64,
    /// The clock is `/clock`'s (`use_sim_time`); a silence of `clock_timeout_s` (wall) is a
    /// fault.
    pub use_sim_time: bool,
    pub clock_timeout_s: f64,
    pub warn_distance_m: f64,
    pub stop_distance_m: f64,
    pub hysteresis_m: f64,
    pub latency_budget_s: f64,
    /// The node publishes the fused state at least this often, s.
    pub heartbeat_period_s: f64,
    /// The QoS deadline offered on the outputs published every heartbeat, s (`None`: infinite).
    pub output_deadline_s: Option<f64>,
    /// A level is lowered only after this many consecutive results allow it.
    pub release_frames: u32,
    /// The stray-point filter (`min_points` 1: off).
    pub stray: StrayFilter,
    pub sources: Vec<SourceConfig>,
    pub static_transforms: Vec<TransformStamped>,
    pub fixed_joint_state: Vec<(String, f64)>,
    /// Known objects whose points are dropped before the query (`cloud::exclusion`).
    pub exclusion_volumes: Vec<ExclusionVolume>,
    /// Shapes joined to the robot's links (`robot::attach`).
    pub attached_objects: Vec<AttachedObject>,
    /// Speed and separation monitoring.
    pub ssm: SsmParams,
    /// Whether the live node publishes its log on `/rosout` (`--disable-rosout-logs`; not a
    /// parameter).
    pub rosout: bool,
    /// Output topic remappings of the live node (`--ros-args -r FROM:=TO`; not a parameter).
    pub remaps: Vec<(String, String)>,
    /// The values as given (flattened names; a declared default is not in it), and the folder
    /// relative paths were taken from: what a change at run time is validated with
    /// (`runtime`).
    values: BTreeMap<String, Yaml>,
    base: Option<PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Self::from_values("ist_monitor", "/", None, BTreeMap::new())
            .expect("the declared defaults are valid")
    }
}

/// Parses `name:=value` (a `-p` override; the value is YAML).
pub fn parse_override(s: &str) -> Result<(String, String), String> {
    let (name, value) = s
        .split_once(":=")
        .ok_or_else(|| format!("expected NAME:=VALUE, got '{s}'"))?;
    Ok((name.trim().to_owned(), value.trim().to_owned()))
}

impl Config {
    /// Reads a parameters file (its first section, whatever its key, which names the node),
    /// then applies `overrides` (`name`, YAML value).
    pub fn load(path: &Path, overrides: &[(String, String)]) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&text, path, overrides)
    }

    /// As [`Config::load`], from the text of the file at `path`.
    pub fn parse(
        text: &str,
        path: &Path,
        overrides: &[(String, String)],
    ) -> Result<Self, ConfigError> {
        let (key, section) = files::first_section(path, text)?;
        let (namespace, node_name) = files::key_name(&key);
        let mut values = BTreeMap::new();
        flatten("", &section, &mut values);
        for (name, value) in overrides {
            values.insert(name.clone(), scalar_yaml(value));
        }
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_values(&node_name, &namespace, Some(base), values)
    }

    /// The declared defaults with `overrides` (`name`, YAML value) applied, for a node named
    /// `ist_monitor`; relative paths are taken from the current folder. The command line reads
    /// its query options through this, so that they have the parameters' defaults and checks.
    pub fn from_overrides(overrides: &[(String, String)]) -> Result<Self, ConfigError> {
        let values = overrides
            .iter()
            .map(|(name, value)| (name.clone(), scalar_yaml(value)))
            .collect();
        Self::from_values("ist_monitor", "/", Some(Path::new(".")), values)
    }

    /// Validates flattened values; relative paths are taken from `base`.
    pub fn from_values(
        node_name: &str,
        namespace: &str,
        base: Option<&Path>,
        values: BTreeMap<String, Yaml>,
    ) -> Result<Self, ConfigError> {
        let v = Values { values };
        let sources = v.strings("sources")?;
        let transforms = v.strings("static_transforms")?;
        let volumes = v.strings("exclusion_volumes")?;
        let objects = v.strings("attached_objects")?;
        // The lists whose entries declare `<entry>.x` parameters; an entry's name is its
        // parameters' prefix, so it may be used once across them.
        let lists = [
            ("sources", "<source>.", &sources),
            ("static_transforms", "<transform>.", &transforms),
            ("exclusion_volumes", "<volume>.", &volumes),
            ("attached_objects", "<object>.", &objects),
        ];
        let mut seen: BTreeMap<&str, &str> = BTreeMap::new();
        for (list, _, entries) in &lists {
            for e in entries.iter() {
                if let Some(other) = seen.insert(e.as_str(), list) {
                    return Err(Values::bad(
                        list,
                        format!("'{e}' is also an entry of {other}: names must differ"),
                    ));
                }
            }
        }
        // Every given name must be declared, directly or under a listed entry.
        for name in v.values.keys() {
            let declared = PARAMETERS.iter().any(|d| {
                d.name == name
                    || lists.iter().any(|(_, prefix, entries)| {
                        d.name.strip_prefix(prefix).is_some_and(|rest| {
                            entries.iter().any(|e| name == &format!("{e}.{rest}"))
                        })
                    })
            });
            if !declared {
                return Err(ConfigError::Unknown(name.clone()));
            }
        }
        let path = |s: String| {
            let p = PathBuf::from(&s);
            match base {
                Some(b) if p.is_relative() && !s.starts_with("package://") => b.join(p),
                _ => p,
            }
        };
        let mode = match v.string("mode", "mode")?.as_str() {
            "fast" => Mode::Fast,
            "certified" => Mode::Certified,
            "exact" => Mode::Exact,
            other => {
                return Err(Values::bad(
                    "mode",
                    format!("'{other}' (expected fast, certified or exact)"),
                ))
            }
        };
        let max_distance_m = match v.raw("max_distance", "max_distance") {
            Yaml::Real(s) if s == ".inf" => f64::INFINITY,
            _ => v.distance("max_distance", "max_distance")?,
        } as f32;
        let warn_distance_m = v.distance("warn_distance", "warn_distance")?;
        let stop_distance_m = v.distance("stop_distance", "stop_distance")?;
        if stop_distance_m > warn_distance_m {
            return Err(Values::bad(
                "stop_distance",
                format!("{stop_distance_m} m is above warn_distance {warn_distance_m} m"),
            ));
        }
        let hysteresis_m = v.distance("hysteresis", "hysteresis")?;
        let query = QueryOptions {
            mode,
            max_distance_m,
            self_filter_padding_m: v
                .bool("self_filter", "self_filter")?
                .then(|| v.distance("self_filter_padding", "self_filter_padding"))
                .transpose()?
                .map(|x| x as f32),
            per_link: v.bool("per_link", "per_link")?,
            per_link_range_m: match v.raw("per_link_range", "per_link_range") {
                Yaml::Null => (warn_distance_m + hysteresis_m) as f32,
                Yaml::Real(s) if s == ".inf" => f32::INFINITY,
                _ => v.distance("per_link_range", "per_link_range")? as f32,
            },
            backend: match v.string("backend", "backend")?.as_str() {
                "cpu" => Backend::Cpu,
                "gpu" => Backend::Gpu,
                "auto" => Backend::Auto,
                other => {
                    return Err(Values::bad(
                        "backend",
                        format!("'{other}' (expected cpu, gpu or auto)"),
                    ))
                }
            },
            gpu_min_points: v.whole("gpu_min_points")?,
            gpu_min_depth_pixels: v.whole("gpu_min_depth_pixels")?,
        };
        let mut build = BuildOptions::default();
        build.packing.max_spheres = v.count("max_spheres")?;
        build.packing.start_spheres = v.count("start_spheres")?;
        let target_gap = v.distance("target_gap", "target_gap")?;
        if !(target_gap > 0.0 && target_gap.is_finite()) {
            return Err(Values::bad(
                "target_gap",
                "must be a positive number of metres",
            ));
        }
        build.packing.target_gap_m = target_gap as f32;
        let package_paths: Vec<PackagePath> = v
            .strings("package_paths")?
            .iter()
            .map(|s| {
                s.parse::<PackagePath>()
                    .map(|p| PackagePath {
                        dir: path(p.dir.to_string_lossy().into_owned()),
                        ..p
                    })
                    .map_err(|e| Values::bad("package_paths", e))
            })
            .collect::<Result<_, _>>()?;
        // A mesh file of a volume or an object: relative to the parameters file, or through
        // the package paths.
        let resolve = |s: &str| -> Result<PathBuf, String> {
            if s.starts_with("package://") {
                resolve_uri(s, Path::new("."), &package_paths).map_err(|e| format!("{s}: {e}"))
            } else {
                Ok(path(s.to_owned()))
            }
        };
        let exclusion_volumes = shapes::exclusion_volumes(&v, &volumes, &sources, &resolve)?;
        let attached_objects = shapes::attached_objects(&v, &objects, &resolve)?;
        let sources = sources
            .iter()
            .map(|s| {
                let get = |rest: &str| (format!("{s}.{rest}"), format!("<source>.{rest}"));
                let (topic, t) = get("topic");
                let (enabled, e) = get("enabled");
                let (timeout, to) = get("source_timeout");
                let (min, mi) = get("min_range");
                let (max, ma) = get("max_range");
                let (qos, q) = get("qos");
                let (kind, k) = get("type");
                let (info, i) = get("camera_info_topic");
                let kind = match v.string(&kind, &k)?.as_str() {
                    "pointcloud" => SourceKind::PointCloud,
                    "depth_image" => SourceKind::DepthImage,
                    other => {
                        return Err(Values::bad(
                            &kind,
                            format!("'{other}' (expected pointcloud or depth_image)"),
                        ))
                    }
                };
                let topic = v.string(&topic, &t)?;
                let camera_info_topic = match kind {
                    SourceKind::PointCloud => None,
                    SourceKind::DepthImage => Some(
                        v.opt_string(&info, &i)?
                            .unwrap_or_else(|| camera_info_beside(&topic)),
                    ),
                };
                let reliable = match v.string(&qos, &q)?.as_str() {
                    "sensor_data" => false,
                    "reliable" => true,
                    other => {
                        return Err(Values::bad(
                            &qos,
                            format!("'{other}' (expected sensor_data or reliable)"),
                        ))
                    }
                };
                let max_range_m = v.opt_f64(&max, &ma)?;
                if max_range_m.is_some_and(|m| m <= 0.0 || m.is_nan()) {
                    return Err(Values::bad(&max, "must be > 0"));
                }
                let source_timeout_s = v.distance(&timeout, &to)?;
                if source_timeout_s <= 0.0 {
                    return Err(Values::bad(&timeout, "must be > 0"));
                }
                Ok(SourceConfig {
                    name: s.clone(),
                    kind,
                    topic,
                    camera_info_topic,
                    enabled: v.bool(&enabled, &e)?,
                    source_timeout_s,
                    min_range_m: v.distance(&min, &mi)?,
                    max_range_m,
                    reliable,
                })
            })
            .collect::<Result<Vec<_>, ConfigError>>()?;
        let static_transforms = transforms
            .iter()
            .map(|t| {
                let n = |rest: &str| shapes::names(t, "<transform>", rest);
                let (parent, pt) = n("parent_frame");
                let (child, ct) = n("child_frame");
                Ok(TransformStamped {
                    header: Header {
                        stamp: Time::default(),
                        frame_id: v.string(&parent, &pt)?,
                    },
                    child_frame_id: v.string(&child, &ct)?,
                    transform: shapes::transform(&v, t, "<transform>")?,
                })
            })
            .collect::<Result<Vec<_>, ConfigError>>()?;
        let names = v.strings("fixed_joint_state.names")?;
        let positions = v.numbers("fixed_joint_state.positions", "fixed_joint_state.positions")?;
        if names.len() != positions.len() {
            return Err(Values::bad(
                "fixed_joint_state.positions",
                format!("{} values for {} names", positions.len(), names.len()),
            ));
        }
        // A padding that reaches the stop threshold would filter an obstacle at the stop
        // distance as "robot": the stop could never be raised by it.
        // (Compared in f32, the precision the query filters in.)
        if let Some(padding) = query.self_filter_padding_m {
            if padding >= (stop_distance_m - hysteresis_m) as f32 {
                return Err(Values::bad(
                    "self_filter_padding",
                    format!(
                        "{padding} m must stay below stop_distance − hysteresis \
                         ({stop_distance_m} − {hysteresis_m} m): a point filtered as the robot \
                         could never raise the stop"
                    ),
                ));
            }
        }
        let heartbeat_period_s = match v.distance("heartbeat_period", "heartbeat_period")? {
            t if t > 0.0 => t,
            t => {
                return Err(Values::bad(
                    "heartbeat_period",
                    format!("must be > 0, got {t}"),
                ))
            }
        };
        Ok(Self {
            node_name: node_name.to_owned(),
            namespace: namespace.to_owned(),
            robot_description: match v.opt_string("robot_description", "robot_description")? {
                Some(s) if s.trim_start().starts_with('<') => Some(RobotSource::Text(s)),
                Some(s) => Some(RobotSource::File(path(s))),
                None => v
                    .opt_string("robot_description_topic", "robot_description_topic")?
                    .map(RobotSource::Topic),
            },
            package_paths,
            query,
            selection: LinkSelection {
                // An attached object is a link the list cannot have named.
                include: match v.strings("links")? {
                    l if l.is_empty() => l,
                    l => l.into_iter().chain(objects.iter().cloned()).collect(),
                },
                exclude: v.strings("exclude_links")?,
                convex_hull: v.strings("convex_hull_links")?,
            },
            build,
            cache_dir: v.opt_string("cache_dir", "cache_dir")?.map(path),
            joint_states_topic: v.string("joint_states_topic", "joint_states_topic")?,
            tf_tolerance_s: v.distance("tf_tolerance", "tf_tolerance")?,
            joint_state_tolerance_s: v
                .distance("joint_state_tolerance", "joint_state_tolerance")?,
            future_stamp_tolerance_s: v
                .distance("future_stamp_tolerance", "future_stamp_tolerance")?,
            use_sim_time: v.bool("use_sim_time", "use_sim_time")?,
            clock_timeout_s: match v.distance("clock_timeout", "clock_timeout")? {
                t if t > 0.0 => t,
                t => {
                    return Err(Values::bad(
                        "clock_timeout",
                        format!("must be > 0, got {t}"),
                    ))
                }
            },
            warn_distance_m,
            stop_distance_m,
            hysteresis_m,
            latency_budget_s: v.distance("latency_budget", "latency_budget")?,
            release_frames: v.count("release_frames")?,
            stray: StrayFilter {
                min_points: v.count("stray_filter.min_points")?,
                cluster_radius_m: v
                    .distance("stray_filter.cluster_radius", "stray_filter.cluster_radius")?,
                max_rejected: v.count("stray_filter.max_rejected")?,
            },
            heartbeat_period_s,
            output_deadline_s: Self::output_deadline(&v, heartbeat_period_s)?,
            sources,
            static_transforms,
            fixed_joint_state: names.into_iter().zip(positions).collect(),
            exclusion_volumes,
            attached_objects,
            ssm: Self::ssm(&v)?,
            remaps: Vec::new(),
            rosout: true,
            base: base.map(Path::to_owned),
            values: v.values,
        })
    }

    /// `output_deadline`: 0 for none, else at least `heartbeat_period` (a deadline shorter than
    /// the period the node publishes at would be missed on every beat).
    fn output_deadline(v: &Values, period: f64) -> Result<Option<f64>, ConfigError> {
        match v.distance("output_deadline", "output_deadline")? {
            0.0 => Ok(None),
            t if t >= period => Ok(Some(t)),
            t => Err(Values::bad(
                "output_deadline",
                format!("must be 0 (none) or at least heartbeat_period ({period} s), got {t}"),
            )),
        }
    }

    fn ssm(v: &Values) -> Result<SsmParams, ConfigError> {
        let d = |name: &str| v.distance(name, name);
        let stopping = StoppingTable {
            speeds_mps: v.numbers(
                "speed_scaling.stopping.speeds",
                "speed_scaling.stopping.speeds",
            )?,
            times_s: v.numbers(
                "speed_scaling.stopping.times",
                "speed_scaling.stopping.times",
            )?,
            distances_m: v.numbers(
                "speed_scaling.stopping.distances",
                "speed_scaling.stopping.distances",
            )?,
        };
        stopping.validate().map_err(|(list, message)| {
            Values::bad(&format!("speed_scaling.stopping.{list}"), message)
        })?;
        let hysteresis = d("speed_scaling.hysteresis")?;
        if hysteresis > 1.0 {
            return Err(Values::bad(
                "speed_scaling.hysteresis",
                format!("{hysteresis} is above 1 (the factor's range)"),
            ));
        }
        Ok(SsmParams {
            enabled: v.bool("speed_scaling.enabled", "speed_scaling.enabled")?,
            human_speed_mps: d("speed_scaling.human_speed")?,
            reaction_time_s: d("speed_scaling.reaction_time")?,
            stopping,
            intrusion_distance_m: d("speed_scaling.intrusion_distance")?,
            sensor_uncertainty_m: d("speed_scaling.sensor_uncertainty")?,
            robot_uncertainty_m: d("speed_scaling.robot_uncertainty")?,
            hysteresis,
            max_increase_rate_per_s: d("speed_scaling.max_increase_rate")?,
            velocities_scaled: v.bool(
                "speed_scaling.velocities_scaled",
                "speed_scaling.velocities_scaled",
            )?,
        })
    }

    /// Where the robot comes from, with `package://` resolved. A safety monitor never guesses
    /// its robot: with neither `robot_description` nor `robot_description_topic` this is an
    /// error naming them.
    pub fn robot_source(&self) -> Result<RobotSource, ConfigError> {
        let bad = |message: String| ConfigError::Invalid {
            name: "robot_description".into(),
            message,
        };
        match &self.robot_description {
            None => Err(bad(
                "not set: the monitor needs the robot's URDF (a file, a package:// \
                 URI or the URDF text), or robot_description_topic"
                    .into(),
            )),
            Some(RobotSource::File(p)) => {
                match p.to_str().filter(|s| s.starts_with("package://")) {
                    Some(uri) => resolve_uri(uri, Path::new("."), &self.package_paths)
                        .map(RobotSource::File)
                        .map_err(|e| bad(format!("{uri}: {e}"))),
                    None => Ok(RobotSource::File(p.clone())),
                }
            }
            Some(other) => Ok(other.clone()),
        }
    }

    /// The URDF file of `robot_description` (an error when the robot comes as text or from a
    /// topic).
    pub fn robot_urdf(&self) -> Result<PathBuf, ConfigError> {
        match self.robot_source()? {
            RobotSource::File(p) => Ok(p),
            _ => Err(ConfigError::Invalid {
                name: "robot_description".into(),
                message: "not a file".into(),
            }),
        }
    }

    /// The node's fully qualified name, `/ns/name`.
    pub fn node_path(&self) -> String {
        let ns = self.namespace.trim_end_matches('/');
        format!("{ns}/{}", self.node_name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(text: &str, overrides: &[(&str, &str)]) -> Result<Config, ConfigError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("params.yaml");
        std::fs::write(&path, text).unwrap();
        let o: Vec<(String, String)> = overrides
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        Config::load(&path, &o)
    }

    #[test]
    fn defaults_and_a_full_file() {
        let c = Config::default();
        assert_eq!(c.query.mode, Mode::Certified);
        assert_eq!(c.sources.len(), 1);
        assert_eq!(c.sources[0].topic, "/camera/depth/points");
        let c = load(
            "/robots/arm_monitor:\n  ros__parameters:\n    mode: exact\n    max_distance: 1\n    sources: [front, wrist]\n    front:\n      topic: /front/points\n      max_range: 4.5\n    wrist.enabled: false\n    static_transforms: [cam]\n    cam:\n      parent_frame: world\n      child_frame: cam_link\n      translation: [1, 2, 3]\n      rotation: [0, 0, 0, 2]\n    fixed_joint_state:\n      names: [j1]\n      positions: [0.5]\n",
            &[("front.min_range", "0.2")],
        )
        .unwrap();
        assert_eq!(
            (c.namespace.as_str(), c.node_name.as_str()),
            ("/robots", "arm_monitor")
        );
        assert_eq!(c.node_path(), "/robots/arm_monitor");
        assert_eq!(c.query.mode, Mode::Exact);
        assert_eq!(c.query.max_distance_m, 1.0);
        assert_eq!(c.sources[0].max_range_m, Some(4.5));
        assert_eq!(c.sources[0].min_range_m, 0.2);
        assert!(!c.sources[1].enabled);
        assert_eq!(c.static_transforms[0].transform.translation.z, 3.0);
        assert_eq!(c.fixed_joint_state, vec![("j1".to_string(), 0.5)]);
    }

    #[test]
    fn the_library_defaults_are_the_declared_ones() {
        // One default per parameter: the typed defaults of the library equal the table's.
        let c = Config::default();
        assert_eq!(c.query, QueryOptions::default());
        assert_eq!(c.ssm, SsmParams::default());
        assert_eq!(c.selection, LinkSelection::default());
        assert_eq!(c.build, BuildOptions::default());
        assert_eq!(default_of("mode"), Some("certified"));
        assert_eq!(default_of("no_such_parameter"), None);
    }

    #[test]
    fn overrides_are_checked_like_a_file() {
        let o = |n: &str, v: &str| vec![(n.to_owned(), v.to_owned())];
        let c = Config::from_overrides(&o("mode", "exact")).unwrap();
        assert_eq!(c.query.mode, Mode::Exact);
        let e = Config::from_overrides(&o("max_distance", "-2"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("max_distance"), "{e}");
    }

    #[test]
    fn auto_takes_each_input_kind_at_its_own_crossover() {
        let o = |n: &str, v: &str| (n.to_owned(), v.to_owned());
        let c = Config::from_overrides(&[
            o("gpu_min_points", "1000000"),
            o("gpu_min_depth_pixels", "1000"),
        ])
        .unwrap();
        let q = &c.query;
        assert_eq!(
            (q.gpu_min_points, q.gpu_min_depth_pixels),
            (1_000_000, 1_000)
        );
        // A 640 × 480 depth image goes to the GPU, a cloud of as many points does not.
        assert!(q.wants_gpu_for_depth(307_200) && !q.wants_gpu(307_200));
        assert!(!q.wants_gpu_for_depth(999) && q.wants_gpu(1_000_000));
        for (backend, both) in [("cpu", false), ("gpu", true)] {
            let c = Config::from_overrides(&[o("backend", backend)]).unwrap();
            assert_eq!(c.query.wants_gpu(1), both);
            assert_eq!(c.query.wants_gpu_for_depth(usize::MAX), both);
        }
    }

    #[test]
    fn no_robot_description_is_an_error_naming_it() {
        let e = Config::default().robot_urdf().unwrap_err().to_string();
        assert!(e.contains("robot_description"), "{e}");
    }

    #[test]
    fn bad_values_name_the_parameter() {
        let base = "ist_monitor:\n  ros__parameters:\n";
        for (body, name) in [
            ("    mode: quick\n", "mode"),
            ("    max_distance: -1.0\n", "max_distance"),
            ("    self_filter_padding: x\n", "self_filter_padding"),
            ("    max_distanse: 1.0\n", "max_distanse"),
            ("    sources: [a]\n    a.qos: fast\n", "a.qos"),
            ("    sources: [a]\n    a.source_timeout: 0\n", "a.source_timeout"),
            ("    static_transforms: [t]\n    t.parent_frame: a\n    t.child_frame: b\n    t.rotation: [0, 0, 0, 0]\n", "t.rotation"),
            ("    fixed_joint_state:\n      names: [a, b]\n      positions: [1.0]\n", "fixed_joint_state.positions"),
            ("    stop_distance: 0.5\n", "stop_distance"),
            ("    per_link: 3\n", "per_link"),
            ("    gpu_min_points: 1.5\n", "gpu_min_points"),
            ("    gpu_min_depth_pixels: -640\n", "gpu_min_depth_pixels"),
            ("    speed_scaling:\n      stopping:\n        times: [0.3, 0.1]\n", "speed_scaling.stopping.times"),
            ("    speed_scaling.stopping.speeds: [0.5, 1.0]\n", "speed_scaling.stopping.speeds"),
            ("    speed_scaling.hysteresis: 2\n", "speed_scaling.hysteresis"),
            ("    speed_scaling.human_speed: -1\n", "speed_scaling.human_speed"),
            ("    output_deadline: 0.05\n", "output_deadline"),
            ("    output_deadline: -1\n", "output_deadline"),
            ("    exclusion_volumes: [t]\n    t.size: [1, 1, 1]\n", "t.frame"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.size: [1, 1]\n", "t.size"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.shape: cone\n", "t.shape"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.shape: sphere\n", "t.radius"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.shape: cylinder\n    t.radius: 0.1\n    t.length: -1\n", "t.length"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.size: [1, 1, 1]\n    t.sources: [cam]\n", "t.sources"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.size: [1, 1, 1]\n    t.rotation: [0, 0, 0, 0]\n", "t.rotation"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.size: [1, 1, 1]\n    t.link: x\n", "t.link"),
            ("    exclusion_volumes: [camera]\n", "exclusion_volumes"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.shape: mesh\n", "t.mesh"),
            ("    exclusion_volumes: [t]\n    t.frame: w\n    t.shape: mesh\n    t.mesh: /no/such.stl\n", "t.mesh"),
            ("    attached_objects: [p]\n    p.link: l\n    p.shape: mesh\n    p.mesh: /no/such.stl\n", "p.mesh"),
            ("    attached_objects: [p]\n    p.link: l\n    p.shape: mesh\n    p.mesh: /\n    p.scale: [1, 0, 1]\n", "p.scale"),
            ("    attached_objects: [p]\n    p.size: [1, 1, 1]\n", "p.link"),
            ("    attached_objects: [p]\n    p.link: l\n    p.shape: sphere\n    p.radius: 0\n", "p.radius"),
        ] {
            let e = load(&format!("{base}{body}"), &[]).unwrap_err().to_string();
            assert!(e.contains(name), "{body}: {e}");
        }
        let e = load("ist_monitor:\n  params: {}\n", &[]).unwrap_err();
        assert!(matches!(e, ConfigError::NoParameters { .. }));
    }
}
