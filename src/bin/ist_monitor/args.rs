//! Options shared by several subcommands and benches, and their parsers. Options that are also node
//! parameters take their default from the library's parameter table
//! ([`ist_monitor::config::PARAMETERS`]) and go through the same validation as a params file.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;

use ist_monitor::config::{self, Config};
use ist_monitor::ist::{BuildOptions, TreeBuilder};
use ist_monitor::packing::PackingParams;
use ist_monitor::query::{Backend, Mode};
use ist_monitor::robot::{LinkSelection, PackagePath, RobotModel};

use crate::choice::choice;
use crate::demo;
use ist_monitor::choice::Choice;

/// A ROS 2 parameters file and `-p` overrides, as `replay`, `bench ssm` and `bench monitor`
/// take them.
#[derive(Args)]
pub struct ConfigArgs {
    /// ROS 2 parameters file (default: config/demo_arm.yaml; bench monitor:
    /// config/panda_perception_tutorial.yaml).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Override a parameter, NAME:=VALUE (value in YAML); repeatable.
    #[arg(short = 'p', long = "param", value_name = "NAME:=VALUE", value_parser = config::parse_override)]
    pub params: Vec<(String, String)>,
}

impl ConfigArgs {
    /// The file given, or the demo file `default`, with the overrides, then `extra`.
    pub fn load(&self, default: &str, extra: &[(String, String)]) -> Result<Config> {
        let mut params = self.params.clone();
        params.extend_from_slice(extra);
        load_config(&self.config, default, &params)
    }
}

/// The config file given, or the demo file `default`, with `params` applied.
pub fn load_config(
    path: &Option<PathBuf>,
    default: &str,
    params: &[(String, String)],
) -> Result<Config> {
    let path = demo::or_demo(path, default)?;
    Config::load(&path, params).with_context(|| format!("config {}", path.display()))
}

/// The declared default of a node parameter (clap shows it in `--help`).
pub fn param(name: &str) -> &'static str {
    config::default_of(name).unwrap_or("")
}

#[derive(Args)]
pub struct RobotArgs {
    /// URDF file (default: the demo robot, urdf/demo_arm.urdf).
    #[arg(long)]
    pub urdf: Option<PathBuf>,
    /// Where package://NAME is found; repeatable.
    #[arg(long = "package-path", value_name = "NAME=DIR")]
    pub package_paths: Vec<PackagePath>,
}

impl RobotArgs {
    /// The robot, with the meshes of the links `selection` selects.
    pub fn load(&self, selection: &LinkSelection) -> Result<RobotModel> {
        let urdf = demo::or_demo(&self.urdf, demo::URDF)?;
        RobotModel::load(&urdf, &self.package_paths, selection)
            .with_context(|| format!("loading robot {}", urdf.display()))
    }
}

#[derive(Args)]
pub struct PackingArgs {
    /// Most spheres per link: the budget starts at --start-spheres and grows (at most doubling)
    /// while the link's certified h is above its target (parameter max_spheres; equal to
    /// --start-spheres for a fixed budget).
    #[arg(long, default_value = param("max_spheres"))]
    pub max_spheres: u32,
    /// The sphere budget a link starts with (parameter start_spheres).
    #[arg(long, default_value = param("start_spheres"))]
    pub start_spheres: u32,
    /// Smallest sphere radius, m.
    #[arg(long, default_value_t = PackingParams::default().min_radius_m)]
    min_radius: f32,
    /// Stop packing a link at this volume coverage (0..1].
    #[arg(long, default_value_t = PackingParams::default().target_coverage)]
    target_coverage: f64,
    /// Prototypes of the first grid per collision element.
    #[arg(long, default_value_t = PackingParams::default().prototypes)]
    prototypes: u32,
    /// The surface gap h a link is packed for, m: the gap pass fills pockets under the surface
    /// and the budget grows until h is at most this (parameter target_gap).
    #[arg(long, default_value = param("target_gap"))]
    target_gap: f32,
    /// A large link is packed for this share of its bounding box's diagonal where that is
    /// above --target-gap; 0: --target-gap on every link (parameter target_gap_per_m).
    #[arg(long, default_value = param("target_gap_per_m"))]
    target_gap_per_m: f32,
    /// Hierarchy build.
    #[arg(long, value_parser = choice::<TreeBuilder>(), default_value = BuildOptions::default().tree.name())]
    tree: TreeBuilder,
}

impl PackingArgs {
    pub fn options(&self) -> Result<BuildOptions> {
        if self.max_spheres == 0 || self.start_spheres == 0 {
            bail!("--max-spheres and --start-spheres must be at least 1");
        }
        if !(self.min_radius > 0.0 && self.min_radius.is_finite()) {
            bail!("--min-radius must be a positive number of metres");
        }
        if !(self.target_coverage > 0.0 && self.target_coverage <= 1.0) {
            bail!("--target-coverage must lie in (0, 1]");
        }
        if self.prototypes == 0 {
            bail!("--prototypes must be at least 1");
        }
        if !(self.target_gap > 0.0 && self.target_gap.is_finite()) {
            bail!("--target-gap must be a positive number of metres");
        }
        if !(self.target_gap_per_m >= 0.0 && self.target_gap_per_m.is_finite()) {
            bail!("--target-gap-per-m must be a finite number ≥ 0");
        }
        Ok(BuildOptions {
            packing: PackingParams {
                max_spheres: self.max_spheres,
                start_spheres: self.start_spheres,
                min_radius_m: self.min_radius,
                target_coverage: self.target_coverage,
                prototypes: self.prototypes,
                target_gap_m: self.target_gap,
                target_gap_per_m: self.target_gap_per_m,
                ..PackingParams::default()
            },
            tree: self.tree,
            ..BuildOptions::default()
        })
    }
}

/// A robot and how its trees are built and cached (`build`, `query`).
#[derive(Args)]
pub struct TreeArgs {
    #[command(flatten)]
    pub robot: RobotArgs,
    #[command(flatten)]
    pub packing: PackingArgs,
    /// Cache folder (default: $IST_MONITOR_CACHE, $XDG_CACHE_HOME/ist_monitor or ~/.cache/ist_monitor).
    #[arg(long)]
    pub cache_dir: Option<PathBuf>,
}

/// The query's options: each is a node parameter of the same name, with the table's default;
/// they are validated into the library's options by [`Config`], as a params file would be.
#[derive(Args)]
pub struct QueryParams {
    /// fast (inner-sphere distance, an upper bound), certified (also the lower bound d − h) or
    /// exact (distance to the collision meshes).
    #[arg(long, value_parser = choice::<Mode>(), default_value = param("mode"))]
    pub mode: Mode,
    /// Drop points farther than this from the robot's bounding box, m (.inf keeps all).
    #[arg(long, default_value = param("max_distance"))]
    pub max_distance: String,
    /// Self-filter padding, m: points this close to the robot are the robot itself.
    #[arg(long, default_value = param("self_filter_padding"))]
    pub self_filter_padding: String,
    /// Take every point as an obstacle, even on the robot (self_filter: false).
    #[arg(long)]
    pub no_self_filter: bool,
    /// Only the global minimum (per_link: false; one shared bound, faster).
    #[arg(long)]
    pub no_per_link: bool,
    /// Per-link minima are measured up to this distance, m; farther links are reported as
    /// "farther than" a certified bound (default: warn_distance + hysteresis; .inf: all).
    #[arg(long)]
    pub per_link_range: Option<String>,
    /// Only these links (comma separated).
    #[arg(long, value_delimiter = ',')]
    pub links: Vec<String>,
    /// Leave these links out (comma separated).
    #[arg(long, value_delimiter = ',')]
    pub exclude_links: Vec<String>,
    /// Pack these links' convex hulls instead of their meshes (comma separated; '*': all); their
    /// distance is then the certified lower bound.
    #[arg(long, value_delimiter = ',')]
    pub convex_hull_links: Vec<String>,
    /// cpu, gpu, or auto (on a hardware GPU, the GPU for clouds from --gpu-min-points points
    /// and depth images from --gpu-min-depth-pixels pixels on).
    #[arg(long, value_parser = choice::<Backend>(), default_value = param("backend"))]
    pub backend: Backend,
    /// Crossover of --backend auto for clouds, in points.
    #[arg(long, default_value = param("gpu_min_points"))]
    pub gpu_min_points: usize,
    /// Crossover of --backend auto for depth images, in pixels.
    #[arg(long, default_value = param("gpu_min_depth_pixels"))]
    pub gpu_min_depth_pixels: usize,
}

impl QueryParams {
    /// The options as `-p NAME:=VALUE` overrides of the node's parameters.
    pub fn overrides(&self) -> Vec<(String, String)> {
        // Quoted: a bare `*` is a YAML alias.
        let list = |v: &[String]| {
            let items: Vec<String> = v.iter().map(|s| format!("{s:?}")).collect();
            format!("[{}]", items.join(", "))
        };
        let range = self.per_link_range.clone();
        [
            ("mode", self.mode.name().to_owned()),
            ("max_distance", self.max_distance.clone()),
            ("self_filter_padding", self.self_filter_padding.clone()),
            ("self_filter", (!self.no_self_filter).to_string()),
            ("per_link", (!self.no_per_link).to_string()),
            ("links", list(&self.links)),
            ("exclude_links", list(&self.exclude_links)),
            ("convex_hull_links", list(&self.convex_hull_links)),
            ("backend", self.backend.name().to_owned()),
            ("gpu_min_points", self.gpu_min_points.to_string()),
            (
                "gpu_min_depth_pixels",
                self.gpu_min_depth_pixels.to_string(),
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_owned(), v))
        .chain(range.map(|r| ("per_link_range".to_owned(), r)))
        .collect()
    }

    /// The validated options (query, link selection) through the parameter table.
    pub fn config(&self) -> Result<Config> {
        Ok(Config::from_overrides(&self.overrides())?)
    }
}

/// Parses a count of at least 1.
pub fn parse_count(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n >= 1 => Ok(n),
        Ok(_) => Err("must be at least 1".into()),
        Err(e) => Err(format!("'{s}': {e}")),
    }
}

/// Parses "x y z qx qy qz qw" (the quaternion is normalized; it must not be zero).
pub fn parse_pose(s: &str) -> Result<nalgebra::Isometry3<f64>, String> {
    let v: Vec<f64> = s
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|w| !w.is_empty())
        .map(|w| w.parse::<f64>().map_err(|e| format!("'{w}': {e}")))
        .collect::<Result<_, _>>()?;
    if v.len() != 7 || v.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "expected 7 finite numbers \"x y z qx qy qz qw\", got '{s}'"
        ));
    }
    let q = nalgebra::Quaternion::new(v[6], v[3], v[4], v[5]);
    if q.norm() < 1e-9 {
        return Err("the quaternion is zero".into());
    }
    Ok(nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(v[0], v[1], v[2]),
        nalgebra::UnitQuaternion::from_quaternion(q),
    ))
}

/// Parses "NAME=VALUE" with a finite value (radians or metres).
pub fn parse_joint(s: &str) -> Result<(String, f64), String> {
    let (name, value) = s
        .split_once('=')
        .ok_or_else(|| format!("expected NAME=VALUE, got '{s}'"))?;
    let value: f64 = value
        .parse()
        .map_err(|e| format!("joint {name}: '{value}' is not a number: {e}"))?;
    if !value.is_finite() {
        return Err(format!("joint {name}: value must be finite"));
    }
    Ok((name.to_owned(), value))
}

/// Parses a positive, finite number of seconds (or a positive rate).
pub fn parse_positive(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("'{s}': {e}"))?;
    if !(v > 0.0 && v.is_finite()) {
        return Err(format!("'{s}' must be a positive, finite number"));
    }
    Ok(v)
}

/// Parses a finite number of seconds ≥ 0.
pub fn parse_seconds(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|e| format!("'{s}': {e}"))?;
    if !(v >= 0.0 && v.is_finite()) {
        return Err(format!("'{s}' must be a finite number of seconds ≥ 0"));
    }
    Ok(v)
}
