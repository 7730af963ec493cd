//! The typed [`Config`]: the flattened values of a parameters file (or of `-p` overrides, or of
//! a change at run time) validated into the settings every stage reads. Each concern is read by
//! its own file (`query`, `sources`, `poses`, `shapes`, `separation`); here they are put
//! together, with the robot's description, the node's timing and its name.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use yaml_rust2::Yaml;

use super::choices::ParameterChanges;
use super::entries::Entries;
use super::error::ConfigError;
use super::params::scalar_yaml;
use super::sources::{SourceConfig, StrayFilter};
use super::unobserved::Unobserved;
use super::values::Values;
use super::{poses, query, separation, shapes, sources, unobserved};
use crate::cloud::exclusion::ExclusionVolume;
use crate::ist::BuildOptions;
use crate::msg::TransformStamped;
use crate::query::{LinkSelection, QueryOptions};
use crate::robot::{urdf::resolve_uri, AttachedObject, PackagePath};
use crate::separation::SsmParams;

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
    /// Two writers of one source topic, joint or TF frame heard within this of a stamp are
    /// the fault `second_publisher` (`crate::msg::Voices`), s.
    pub second_publisher_window_s: f64,
    /// One voice per source by discovery too: two or more writers matched on a source topic
    /// are the fault `second_publisher` while they are matched.
    pub writers_from_discovery: bool,
    /// Which parameter changes the running node takes.
    pub parameter_changes: ParameterChanges,
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
    /// What no source has seen (`monitor::unseen`).
    pub unobserved: Unobserved,
    /// Whether the live node publishes its log on `/rosout` (`--disable-rosout-logs`; not a
    /// parameter).
    pub rosout: bool,
    /// Output topic remappings of the live node (`--ros-args -r FROM:=TO`; not a parameter).
    pub remaps: Vec<(String, String)>,
    /// The live node's SROS2 enclave (`--ros-args --enclave`; not a parameter): `None` is `/`.
    pub enclave: Option<String>,
    /// The values as given (flattened names; a declared default is not in it), and the folder
    /// relative paths were taken from: what a change at run time is validated with
    /// (`runtime`).
    pub(super) values: BTreeMap<String, Yaml>,
    pub(super) base: Option<PathBuf>,
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

/// Makes a relative path of the file relative to the folder it was read from.
type MakePath<'a> = dyn Fn(String) -> PathBuf + 'a;

impl Config {
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
        let entries = Entries::read(&v)?;
        let path = |s: String| {
            let p = PathBuf::from(&s);
            match base {
                Some(b) if p.is_relative() && !s.starts_with("package://") => b.join(p),
                _ => p,
            }
        };
        let (query, thresholds) = query::query_options(&v)?;
        let build = query::build_options(&v)?;
        let package_paths = Self::package_paths(&v, &path)?;
        // A mesh file of a volume or an object: relative to the parameters file, or through
        // the package paths.
        let resolve = |s: &str| -> Result<PathBuf, String> {
            if s.starts_with("package://") {
                resolve_uri(s, Path::new("."), &package_paths).map_err(|e| format!("{s}: {e}"))
            } else {
                Ok(path(s.to_owned()))
            }
        };
        let exclusion_volumes =
            shapes::exclusion_volumes(&v, &entries.volumes, &entries.sources, &resolve)?;
        let attached_objects = shapes::attached_objects(&v, &entries.objects, &resolve)?;
        let sources = sources::sources(&v, &entries.sources)?;
        let static_transforms = poses::static_transforms(&v, &entries.transforms)?;
        let fixed_joint_state = poses::fixed_joint_state(&v)?;
        query::check_self_filter_padding(&query, &thresholds)?;
        let heartbeat_period_s = Self::positive_s(&v, "heartbeat_period")?;
        Ok(Self {
            node_name: node_name.to_owned(),
            namespace: namespace.to_owned(),
            robot_description: Self::robot_description(&v, &path)?,
            package_paths,
            query,
            selection: query::selection(&v, &entries.objects)?,
            build,
            cache_dir: v.opt_string("cache_dir", "cache_dir")?.map(path),
            joint_states_topic: v.string("joint_states_topic", "joint_states_topic")?,
            tf_tolerance_s: v.distance("tf_tolerance", "tf_tolerance")?,
            joint_state_tolerance_s: v
                .distance("joint_state_tolerance", "joint_state_tolerance")?,
            future_stamp_tolerance_s: v
                .distance("future_stamp_tolerance", "future_stamp_tolerance")?,
            second_publisher_window_s: Self::positive_s(&v, "second_publisher_window")?,
            writers_from_discovery: v.bool("writers_from_discovery", "writers_from_discovery")?,
            parameter_changes: v.choice("parameter_changes", "parameter_changes")?,
            use_sim_time: v.bool("use_sim_time", "use_sim_time")?,
            clock_timeout_s: Self::positive_s(&v, "clock_timeout")?,
            warn_distance_m: thresholds.warn_m,
            stop_distance_m: thresholds.stop_m,
            hysteresis_m: thresholds.hysteresis_m,
            latency_budget_s: v.distance("latency_budget", "latency_budget")?,
            release_frames: v.count("release_frames")?,
            stray: StrayFilter::read(&v)?,
            heartbeat_period_s,
            output_deadline_s: Self::output_deadline(&v, heartbeat_period_s)?,
            sources,
            static_transforms,
            fixed_joint_state,
            exclusion_volumes,
            attached_objects,
            ssm: separation::ssm(&v)?,
            unobserved: unobserved::unobserved(&v)?,
            remaps: Vec::new(),
            enclave: None,
            rosout: true,
            base: base.map(Path::to_owned),
            values: v.values,
        })
    }

    /// `robot_description` (a file, a `package://` URI or the URDF text), else
    /// `robot_description_topic`.
    fn robot_description(v: &Values, path: &MakePath) -> Result<Option<RobotSource>, ConfigError> {
        Ok(
            match v.opt_string("robot_description", "robot_description")? {
                Some(s) if s.trim_start().starts_with('<') => Some(RobotSource::Text(s)),
                Some(s) => Some(RobotSource::File(path(s))),
                None => v
                    .opt_string("robot_description_topic", "robot_description_topic")?
                    .map(RobotSource::Topic),
            },
        )
    }

    /// `package_paths` (`NAME=DIR`), each folder relative to the file.
    fn package_paths(v: &Values, path: &MakePath) -> Result<Vec<PackagePath>, ConfigError> {
        v.strings("package_paths")?
            .iter()
            .map(|s| {
                s.parse::<PackagePath>()
                    .map(|p| PackagePath {
                        dir: path(p.dir.to_string_lossy().into_owned()),
                        ..p
                    })
                    .map_err(|e| Values::bad("package_paths", e))
            })
            .collect()
    }

    /// A period or timeout that must be > 0, s.
    fn positive_s(v: &Values, name: &str) -> Result<f64, ConfigError> {
        match v.distance(name, name)? {
            t if t > 0.0 => Ok(t),
            t => Err(Values::bad(name, format!("must be > 0, got {t}"))),
        }
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
    use crate::config::params::default_of;
    use crate::query::Mode;

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
