//! The declaration of every parameter: its name, default (YAML text), unit and meaning, the one
//! table that the loader checks names against, `ist_monitor params` prints and `config/README.md`
//! shows.

use yaml_rust2::{Yaml, YamlLoader};

use super::choices::{
    ParameterChanges, SelfShadow, ShapeKind, SourceKind, SourceQos, UnobservedPolicy,
};
use crate::choice::Choice;
use crate::query::{Backend, Mode};

/// A YAML value from its text: a declared default, or a `-p` override (`Null` where the text is
/// not YAML).
pub(super) fn scalar_yaml(text: &str) -> Yaml {
    YamlLoader::load_from_str(text)
        .ok()
        .and_then(|d| d.into_iter().next())
        .unwrap_or(Yaml::Null)
}

/// One declared parameter. `default` is YAML text; `~` means "no value" (optional).
#[derive(Debug, Clone, Copy)]
pub struct ParamDecl {
    pub name: &'static str,
    pub default: &'static str,
    pub unit: &'static str,
    pub doc: &'static str,
    /// Settable at run time (the node's `set_parameters` services); every other parameter is
    /// read-only once the node runs.
    pub settable: bool,
    /// For a parameter that names one value of an enum: that enum's names. The config reads
    /// such a parameter only through its declaration (`Values::choice`), and the node's
    /// parameter descriptor lists the names.
    pub one_of: Option<OneOf>,
}

/// The values a parameter may name: those of a [`Choice`], taken from the enum itself.
#[derive(Debug, Clone, Copy)]
pub struct OneOf {
    /// "a, b or c".
    pub names: fn() -> String,
    /// Whether a text names one of them.
    pub accepts: fn(&str) -> bool,
}

fn accepts<T: Choice>(text: &str) -> bool {
    T::parse(text).is_some()
}

/// `decl`, naming one value of `T`.
const fn one_of<T: Choice>(decl: ParamDecl) -> ParamDecl {
    ParamDecl {
        one_of: Some(OneOf {
            names: T::names,
            accepts: accepts::<T>,
        }),
        ..decl
    }
}

/// A parameter set at start only.
const fn p(
    name: &'static str,
    default: &'static str,
    unit: &'static str,
    doc: &'static str,
) -> ParamDecl {
    ParamDecl {
        name,
        default,
        unit,
        doc,
        settable: false,
        one_of: None,
    }
}

/// A parameter that may also be set while the node runs (`node::parameters`: validated as at
/// start, applied whole or not at all, and nothing that would weaken protection while the safety
/// stop is raised).
const fn rt(
    name: &'static str,
    default: &'static str,
    unit: &'static str,
    doc: &'static str,
) -> ParamDecl {
    ParamDecl {
        settable: true,
        ..p(name, default, unit, doc)
    }
}

/// Every parameter of the node. `<source>.x`, `<transform>.x`, `<volume>.x` and `<object>.x`
/// are declared for each name in `sources`, `static_transforms`, `exclusion_volumes` and
/// `attached_objects`.
pub const PARAMETERS: &[ParamDecl] = &[
    p("robot_description", "~", "path", "the robot: a URDF file (relative paths are relative to this file), a package:// URI (resolved through package_paths, ROS_PACKAGE_PATH, AMENT_PREFIX_PATH) or the URDF text itself; required unless robot_description_topic is set"),
    p("robot_description_topic", "~", "topic", "without robot_description: the node takes the URDF from this std_msgs/String topic (transient local, as robot_state_publisher publishes /robot_description) and reports 'not monitoring' until it arrives"),
    p("package_paths", "[]", "NAME=DIR", "where package://NAME is found"),
    one_of::<Mode>(p("mode", "certified", "", "fast (inner-sphere distance, an upper bound), certified (also the lower bound d − h) or exact (distance to the collision meshes)")),
    p("max_distance", "2.0", "m", "points farther than this from the robot's bounding box are culled"),
    p("self_filter", "true", "", "drop cloud points on the robot itself"),
    p("self_filter_padding", "0.01", "m", "a point this close to the robot is the robot"),
    p("per_link", "true", "", "also compute the minimum of every link"),
    p("per_link_range", "~", "m", "per-link minima are measured up to this distance; a link farther away is reported as farther than a certified bound, which costs far less (default: warn_distance + hysteresis; .inf: every link measured)"),
    one_of::<Backend>(p("backend", "auto", "", "cpu, gpu, or auto: the GPU for clouds of at least gpu_min_points and depth images of at least gpu_min_depth_pixels on a hardware GPU")),
    p("gpu_min_points", "5000000", "points", "crossover of backend auto for clouds (measure it with `ist_monitor bench gpu`)"),
    p("gpu_min_depth_pixels", "99840", "pixels", "crossover of backend auto for depth images, which the GPU unprojects itself (measure it with `ist_monitor bench gpu --depth`)"),
    p("links", "[]", "", "only these links (empty: all links with collision geometry)"),
    p("exclude_links", "[]", "", "leave these links out"),
    p("convex_hull_links", "[]", "", "pack these links' convex hulls instead of their meshes ([\"*\"]: every link); a hull contains the link, so only its certified lower bound holds for the link, and that is what is published as its distance"),
    p("max_spheres", "65536", "", "most inner spheres per link: a link starts with start_spheres and is given more while its certified surface gap h is above its target (set it to start_spheres for a fixed budget)"),
    p("start_spheres", "8192", "", "the sphere budget a link starts with"),
    p("target_gap", "0.0015", "m", "the surface gap h a link is packed for: the budget grows until h is at most this, or max_spheres is reached"),
    p("target_gap_per_m", "0.0025", "m/m", "a large link is packed for this share of its bounding box's diagonal where that is above target_gap (a 1.2 m link: 3 mm; the finer tree there costs minutes of the first build); 0: target_gap on every link"),
    p("cache_dir", "~", "path", "where the trees are cached (default: $IST_MONITOR_CACHE or ~/.cache/ist_monitor)"),
    p("joint_states_topic", "/joint_states", "topic", "sensor_msgs/JointState input"),
    p("tf_tolerance", "0.1", "s", "a transform may be this much older or newer than the cloud"),
    p("joint_state_tolerance", "0.1", "s", "a joint state may be this much older or newer than the cloud"),
    p("future_stamp_tolerance", "0.1", "s", "a cloud stamped more than this ahead of the clock is a fault (clock skew between machines)"),
    p("second_publisher_window", "1.0", "s", "one voice per input: two writers (DDS writer GUIDs, rmw_zenoh GIDs) of one source topic, one joint or one TF frame, heard within this long of a stamp, are the fault second_publisher (ERROR, no distance, naming the writers) until one of them has been alone this long; a static frame given two different values by two writers stays refused until the node restarts"),
    p("writers_from_discovery", "true", "", "one voice per source, also by discovery: a source topic with two or more writers matched now (DDS SEDP, rmw_zenoh liveliness tokens) is the fault second_publisher for as long as they are matched, whatever reaches the node (a writer whose messages are all lost is still heard), and so is a depth source's CameraInfo topic; on DDS a joint's or a TF frame's writer stays its voice while it is matched; false: only the writers heard through their messages (second_publisher_window)"),
    one_of::<ParameterChanges>(p("parameter_changes", "open", "", "which run-time parameter changes are taken: open (any valid change; while the safety stop is raised one that weakens protection is refused), strengthen_only (a change that weakens protection — a lower stop_distance, hysteresis or release_frames, a volume or object added, a source disabled — is refused at any time) or none (every change refused); not given with ROS_SECURITY_ENABLE=true: strengthen_only (a given open is kept, with a WARN)")),
    p("use_sim_time", "false", "", "take the clock from /clock (rosgraph_msgs/Clock: a simulator, `ros2 bag play --clock`) for the stamp checks, the timeouts, the SSM ages and the output stamps; /clock silent for clock_timeout is a fault, and a jump back in time forgets the transforms, joint states and results received"),
    p("clock_timeout", "1.0", "s", "use_sim_time: /clock silent this long (wall time) is a fault: ERROR, no distance, until it ticks again"),
    rt("warn_distance", "0.3", "m", "diagnostics WARN below this distance"),
    rt("stop_distance", "0.1", "m", "diagnostics ERROR (and safety stop) below this distance"),
    rt("hysteresis", "0.02", "m", "a level is left only this far beyond its threshold"),
    rt("latency_budget", "0.05", "s", "processing slower than this is reported in the diagnostics"),
    rt("release_frames", "1", "frames", "a level is lowered only after this many consecutive results allow it (raising is immediate); the delay adds (release_frames − 1) frame periods to the time a stop is held, never to the reaction time"),
    rt("stray_filter.min_points", "1", "points", "a source's nearest point counts only when at least this many of its valid points (itself included) lie within stray_filter.cluster_radius of it; a nearer isolated point is rejected and the query repeated without it. 1: off. The distance is then that of the nearest cluster of min_points points, not of the nearest point"),
    rt("stray_filter.cluster_radius", "0.02", "m", "the radius of a cluster for stray_filter.min_points"),
    rt("stray_filter.max_rejected", "16", "points", "at most this many points are rejected per frame; the nearest point after that counts whatever its neighbours (the conservative side)"),
    p("heartbeat_period", "0.1", "s", "the node publishes the cell's fused state at least this often, also when no cloud arrives, so that a subscriber can tell a quiet monitor from a dead one (> 0)"),
    p("output_deadline", "0.5", "s", "the QoS deadline offered on every output published each heartbeat (all but ~/min_distance, which only carries a known distance; ~/speed_scaling with the separation monitor on): a DDS subscriber that requests this deadline or a longer one is matched, and its middleware tells it when no message came within it (a node killed without its last word, or hung). 0: none (infinite). At least heartbeat_period. Over zenoh only announced: rmw_zenoh enforces no deadline"),
    p("sources", "[camera]", "", "names of the point cloud sources"),
    one_of::<SourceKind>(p("<source>.type", "pointcloud", "", "pointcloud (sensor_msgs/PointCloud2) or depth_image (sensor_msgs/Image 16UC1 in mm or 32FC1 in m, with its sensor_msgs/CameraInfo; points made as depth_image_proc makes them)")),
    p("<source>.topic", "/camera/depth/points", "topic", "the source's PointCloud2 or depth Image topic"),
    p("<source>.camera_info_topic", "~", "topic", "depth_image: the CameraInfo topic (default: camera_info beside the image topic, as image_transport pairs them)"),
    rt("<source>.enabled", "true", "", "whether the source is used"),
    p("<source>.source_timeout", "0.5", "s", "no cloud for this long, or a cloud stamped longer ago than this, is a fault (as Nav2's collision monitor)"),
    p("<source>.min_range", "0.0", "m", "points nearer the sensor than this are dropped"),
    p("<source>.max_range", "~", "m", "points farther from the sensor than this are dropped (default: none)"),
    one_of::<SourceQos>(p("<source>.qos", "sensor_data", "", "sensor_data (best effort) or reliable")),
    p("<source>.range_noise", "0.02", "m", "unobserved space: a return at range r shows the ray free up to r − range_noise (the sensor's depth noise where the cell is; 2 cm: a Kinect-class camera at 3 m)"),
    one_of::<UnobservedPolicy>(p("unobserved", "report", "", "what no source has seen: ignore (not computed, costs nothing), report (the distance to a hidden body of detection_capability on ~/unseen_distance (+inf: none can hide, NaN: the pass failed), ~/unseen_link_distances, markers coloured by cause and /diagnostics; levels unchanged) or protect (also the level, the safety stop and, per link, the speed-scaling factor take the smaller of the seen and the unseen distance; a failed or late pass is a fault)")),
    one_of::<SelfShadow>(p("unobserved_self_shadow", "count", "", "the robot's own shadow (places the robot hides from every camera that could see them): count (as any hidden space: with one camera the unseen distance is then 0 beside the arm) or apart (reported on its own, self_shadow_distance_m in /diagnostics, left out of ~/unseen_distance and of protect: the stated assumption that nothing of the detection capability hides there)")),
    p("unobserved_resolution", "0.02", "m", "the cell size of the unobserved-space grid over monitored_volume"),
    p("detection_capability", "0.07", "m", "the diameter of the smallest body that must be caught where no camera sees (ISO 13855 / IEC 61496: 70 mm detects an arm); a place counts hidden only where a body of it can be, judged by every pixel of its footprint. More than the grid's cell diagonal (3.46 cm at 2 cm)"),
    p("monitored_volume.frame", "~", "frame", "the frame the monitored volume is fixed in (default: the robot's root link)"),
    p("monitored_volume.size", "~", "m", "the monitored volume, a box: edge lengths [x, y, z] (default: the robot's reach plus monitored_volume.margin on every side in x and y, and from the root's z = 0 plane, taken as the floor, up to the reach plus the margin)"),
    p("monitored_volume.translation", "[0.0, 0.0, 0.0]", "m", "frame_from_box translation x y z (the box's centre), with monitored_volume.size"),
    p("monitored_volume.rotation", "[0.0, 0.0, 0.0, 1.0]", "", "frame_from_box rotation as a quaternion x y z w, with monitored_volume.size"),
    p("monitored_volume.margin", "0.3", "m", "without monitored_volume.size: what the default box adds to the robot's reach"),
    p("unobserved_markers", "256", "cells", "most hidden places drawn on ~/closest_points (namespace unseen, coloured by cause), the nearest to the robot first: where a second camera would help; the node draws them only while the topic has a reader. 0: none"),
    p("static_transforms", "[]", "", "names of static transforms given here, for bags and setups without /tf_static"),
    p("<transform>.parent_frame", "~", "frame", "parent frame of the static transform"),
    p("<transform>.child_frame", "~", "frame", "child frame of the static transform"),
    p("<transform>.translation", "[0.0, 0.0, 0.0]", "m", "parent_from_child translation x y z"),
    p("<transform>.rotation", "[0.0, 0.0, 0.0, 1.0]", "", "parent_from_child rotation as a quaternion x y z w"),
    rt("exclusion_volumes", "[]", "", "names of exclusion volumes: known objects of the cell (a table, a fixture, a conveyor) whose points are dropped before the query, counted per volume in the diagnostics (points_excluded.<volume>) and drawn in RViz. A person inside one is not seen"),
    rt("<volume>.frame", "~", "frame", "the TF frame (or robot link) the volume is fixed in; required. It is looked up at each cloud's stamp as the sensor's frame is: a missing transform is a fault"),
    one_of::<ShapeKind>(rt("<volume>.shape", "box", "", "box (size), sphere (radius) or cylinder (radius, length; axis z), centred on translation; or mesh (mesh, scale, padding)")),
    rt("<volume>.mesh", "~", "path", "mesh: the mesh file (STL, OBJ, DAE, PLY; relative to the parameters file, or a package:// URI) in the volume's frame; its solid is taken as a robot link's mesh is (closed, filled)"),
    rt("<volume>.scale", "[1.0, 1.0, 1.0]", "", "mesh: scale per axis (each > 0), as a URDF mesh's"),
    rt("<volume>.padding", "0.0", "m", "mesh: points within this distance of the mesh's solid are dropped too. Judged on a grid of signed distances (at most 128 voxels a side): a point beyond the padding never is, one within it less a voxel diagonal always is (the log gives the voxel)"),
    rt("<volume>.size", "~", "m", "box: edge lengths [x, y, z]"),
    rt("<volume>.radius", "~", "m", "sphere or cylinder radius"),
    rt("<volume>.length", "~", "m", "cylinder length along its z axis"),
    rt("<volume>.translation", "[0.0, 0.0, 0.0]", "m", "frame_from_volume translation x y z"),
    rt("<volume>.rotation", "[0.0, 0.0, 0.0, 1.0]", "", "frame_from_volume rotation as a quaternion x y z w"),
    rt("<volume>.sources", "[]", "", "the sources whose points it drops (empty: every source)"),
    rt("attached_objects", "[]", "", "names of attached objects: shapes fixed to a robot link that the URDF lacks (a held part, a tool). Each joins the robot as a link of its own, named after it: packed and certified like any link, its points self-filtered, its distance to the world measured and published under its name. Set at run time (a part grasped or released), the robot's trees are rebuilt on a thread of their own, and the node reports ERROR, 'not monitoring', with the safety stop until they are ready"),
    rt("<object>.link", "~", "link", "the robot link it is fixed to; required"),
    one_of::<ShapeKind>(rt("<object>.shape", "box", "", "box (size), sphere (radius) or cylinder (radius, length; axis z), centred on translation; or mesh (mesh, scale)")),
    rt("<object>.mesh", "~", "path", "mesh: the mesh file (STL, OBJ, DAE, PLY; relative to the parameters file, or a package:// URI) in the object's frame, taken in as a robot link's mesh"),
    rt("<object>.scale", "[1.0, 1.0, 1.0]", "", "mesh: scale per axis (each > 0), as a URDF mesh's"),
    rt("<object>.size", "~", "m", "box: edge lengths [x, y, z]"),
    rt("<object>.radius", "~", "m", "sphere or cylinder radius"),
    rt("<object>.length", "~", "m", "cylinder length along its z axis"),
    rt("<object>.translation", "[0.0, 0.0, 0.0]", "m", "link_from_object translation x y z"),
    rt("<object>.rotation", "[0.0, 0.0, 0.0, 1.0]", "", "link_from_object rotation as a quaternion x y z w"),
    p("fixed_joint_state.names", "[]", "", "joints held at fixed values (for bags without /joint_states)"),
    p("fixed_joint_state.positions", "[]", "rad or m", "their values, in the same order"),
    p("speed_scaling.enabled", "true", "", "publish ~/speed_scaling (control_msgs/SpeedScalingFactor) from speed and separation monitoring (ISO/TS 15066); needs joint velocities"),
    p("speed_scaling.human_speed", "1.6", "m/s", "v_h: the speed a person approaches at (ISO 13855 walking speed)"),
    p("speed_scaling.reaction_time", "0.1", "s", "T_r without the cloud's age, which is measured and added per cloud"),
    p("speed_scaling.stopping.speeds", "[0.0, 1.0]", "m/s", "speeds of the stopping table (from 0, increasing); replace the defaults by the robot's stopping measurements"),
    p("speed_scaling.stopping.times", "[0.0, 0.3]", "s", "T_s: stopping time at each speed (linear between, extrapolated beyond)"),
    p("speed_scaling.stopping.distances", "[0.0, 0.15]", "m", "S_s: stopping distance at each speed"),
    p("speed_scaling.intrusion_distance", "0.0", "m", "C: intrusion distance from the sensor's detection capability (ISO 13855)"),
    p("speed_scaling.sensor_uncertainty", "0.02", "m", "Z_d without the surface gap h (added where the distance is the inner-sphere one)"),
    p("speed_scaling.robot_uncertainty", "0.01", "m", "Z_r: robot position uncertainty"),
    p("speed_scaling.hysteresis", "0.05", "", "the factor rises only when the allowed factor exceeds it by this"),
    p("speed_scaling.max_increase_rate", "0.5", "1/s", "largest rise of the factor per second (decreases are immediate)"),
    p("speed_scaling.velocities_scaled", "true", "", "the measured joint velocities already carry the factor in effect (a controller obeying ~/speed_scaling): they are divided by it to get the nominal motion"),
];

/// The parameter table in Markdown, as `config/README.md` shows it (`ist_monitor params`).
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| parameter | default | unit | at run time | meaning |\n|---|---|---|---|---|\n",
    );
    for d in PARAMETERS {
        let default = if d.default == "~" {
            "(none)"
        } else {
            d.default
        };
        let settable = if d.settable { "settable" } else { "" };
        out.push_str(&format!(
            "| `{}` | `{default}` | {} | {settable} | {} |\n",
            d.name, d.unit, d.doc
        ));
    }
    out
}

/// The declared default (YAML text) of parameter `name`; `None` for an undeclared name.
pub fn default_of(name: &str) -> Option<&'static str> {
    PARAMETERS
        .iter()
        .find(|d| d.name == name)
        .map(|d| d.default)
}

/// The type of a parameter's value, as ROS 2 types parameters (`rcl_interfaces/ParameterType`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamKind {
    Bool,
    Integer,
    Double,
    String,
    Doubles,
    Strings,
}

impl ParamDecl {
    /// Whether the unit names a quantity (metres, seconds, points), not a name or a path.
    pub fn is_quantity(&self) -> bool {
        !matches!(
            self.unit,
            "" | "path" | "topic" | "frame" | "link" | "NAME=DIR"
        )
    }

    /// The declared type, read from the default: `2.0` a double, `1` an integer, `[0.0, 1.0]` a
    /// list of doubles. An empty list holds strings unless the unit names a quantity.
    /// `None` for a parameter without a default (`~`): its type is that of the value given.
    pub fn kind(&self) -> Option<ParamKind> {
        let quantity = self.is_quantity();
        match scalar_yaml(self.default) {
            Yaml::Null => None,
            Yaml::Boolean(_) => Some(ParamKind::Bool),
            Yaml::Integer(_) => Some(ParamKind::Integer),
            Yaml::Real(_) => Some(ParamKind::Double),
            Yaml::Array(a) => Some(match a.first() {
                Some(Yaml::String(_)) => ParamKind::Strings,
                Some(_) => ParamKind::Doubles,
                None if quantity => ParamKind::Doubles,
                None => ParamKind::Strings,
            }),
            _ => Some(ParamKind::String),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A parameter that names an enum's value is declared with a default that is one of them.
    #[test]
    fn every_named_value_default_is_one_of_its_names() {
        let named: Vec<&ParamDecl> = PARAMETERS.iter().filter(|d| d.one_of.is_some()).collect();
        assert!(named.iter().any(|d| d.name == "mode"), "mode names a Mode");
        for d in named {
            let one_of = d.one_of.expect("filtered");
            assert!(
                (one_of.accepts)(d.default),
                "{}: default '{}' is not one of {}",
                d.name,
                d.default,
                (one_of.names)()
            );
        }
    }
}
