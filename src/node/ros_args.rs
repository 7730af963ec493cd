//! The ROS 2 command line after `--ros-args`, as rcl parses it: `-r`/`--remap` (`__node:=`,
//! `__ns:=`, and topic remappings `FROM:=TO`, optionally for one node as `NODE:FROM:=TO`),
//! `-p`/`--param NAME:=VALUE`, `--params-file FILE` (repeatable), `--log-level [NAME:=]LEVEL`,
//! `--enable-`/`--disable-rosout-logs`, `-e`/`--enclave ENCLAVE` (the SROS2 enclave, an
//! absolute name as rcl validates it: `security`), and the arguments that concern rcl's own
//! logging (`--log-config-file`, `--enable-`/`--disable-stdout-logs`, `-external-lib-logs`),
//! which are taken and noted: the node has no rcl underneath. Anything else is refused naming it. A launch file
//! starts the node with exactly these (launch_ros's `Node(name=, namespace=, parameters=,
//! remappings=, ros_arguments=)`).
//!
//! Topic names expand as ROS 2 expands them (`~/x` private, `x` in the namespace, `/x`
//! absolute), and a remapping applies to every topic the node uses, inputs and outputs alike:
//! rcl matches the expanded `FROM` against the expanded topic name. Here too the names the
//! middleware is given: a topic's ROS 2 name ([`topic_name`]), an input topic as the node
//! subscribes to it ([`input_topic`]) and a message type's (`pkg/msg/Type`, [`type_name`]).

use std::path::PathBuf;

use ros2_client::{MessageTypeName, Name};

use super::error::{entity, NodeError, Result};
use super::security::validate_enclave_name;
use crate::config::Config;
use crate::msg::RosMessage;

/// The node's ROS arguments.
#[derive(Debug, Default, Clone)]
pub struct RosArgs {
    pub node: Option<String>,
    pub namespace: Option<String>,
    /// Topic remappings in the order given: `(node, FROM, TO)`, `node` set for `NODE:FROM:=TO`
    /// (which applies only to the node of that name). `FROM` as given (`~/x`, `x` or `/x`).
    pub remaps: Vec<(Option<String>, String, String)>,
    /// `-p NAME:=VALUE` (YAML values), applied after every parameters file.
    pub params: Vec<(String, String)>,
    /// `--params-file`, in order: a later file's value wins.
    pub params_files: Vec<PathBuf>,
    /// `--log-level`: `(logger, level)`; `None` for the default level.
    pub log_levels: Vec<(Option<String>, log::LevelFilter)>,
    /// `--enable-rosout-logs` / `--disable-rosout-logs` (the node's log on `/rosout`, on
    /// unless disabled).
    pub rosout: Option<bool>,
    /// `--enclave`: the SROS2 enclave (validated; used with `ROS_SECURITY_ENABLE=true`).
    pub enclave: Option<String>,
    /// Arguments taken but without effect here, with why (for the log).
    pub noted: Vec<String>,
}

/// A ROS 2 logging level as `--log-level` takes it (case-insensitive); FATAL is our ERROR and
/// UNSET the default.
fn log_level(text: &str) -> Option<Option<log::LevelFilter>> {
    Some(match text.to_ascii_lowercase().as_str() {
        "debug" => Some(log::LevelFilter::Debug),
        "info" => Some(log::LevelFilter::Info),
        "warn" | "warning" => Some(log::LevelFilter::Warn),
        "error" | "fatal" => Some(log::LevelFilter::Error),
        "unset" => None,
        _ => return None,
    })
}

impl RosArgs {
    /// The topic remappings that apply to the node named `node` (rules for other nodes left
    /// out), `(FROM, TO)` in order.
    pub fn remaps_for(&self, node: &str) -> Vec<(String, String)> {
        (self.remaps.iter())
            .filter(|(n, _, _)| n.as_deref().is_none_or(|n| n == node))
            .map(|(_, from, to)| (from.clone(), to.clone()))
            .collect()
    }

    /// The level `--log-level` sets for the node's logger: a rule naming the node (`NAME` or
    /// its logger name, the namespace joined with dots: `cell1.ist_monitor`) wins over the
    /// default level; rules for other loggers (rcl, rmw) have nothing to set here.
    pub fn log_level_for(&self, node: &str, namespace: &str) -> Option<log::LevelFilter> {
        let dotted = format!("{}.{node}", namespace.trim_matches('/').replace('/', "."));
        let logger = dotted.trim_start_matches('.');
        let named = (self.log_levels.iter())
            .filter(|(n, _)| n.as_deref().is_some_and(|n| n == node || n == logger))
            .map(|(_, l)| *l)
            .next_back();
        named.or_else(|| {
            (self.log_levels.iter())
                .filter(|(n, _)| n.is_none())
                .map(|(_, l)| *l)
                .next_back()
        })
    }
}

/// A topic name as ROS 2 expands it for the node at `node_path` (`/ns/name`): `~/x` is private
/// to the node, `x` lies in its namespace, `/x` is absolute.
pub fn expand_topic(name: &str, node_path: &str) -> String {
    let node_path = node_path.trim_end_matches('/');
    if name == "~" {
        return node_path.to_owned();
    }
    if let Some(rest) = name.strip_prefix("~/") {
        return format!("{node_path}/{rest}");
    }
    if name.starts_with('/') {
        return name.to_owned();
    }
    let ns = node_path.rsplit_once('/').map_or("", |(ns, _)| ns);
    format!("{ns}/{name}")
}

/// The topic `full` (fully qualified) after the first remapping whose `FROM` expands to it.
pub fn remap_topic(full: &str, remaps: &[(String, String)], node_path: &str) -> String {
    remaps
        .iter()
        .find(|(from, _)| expand_topic(from, node_path) == full)
        .map_or_else(|| full.to_owned(), |(_, to)| expand_topic(to, node_path))
}

/// The topic the node uses for `name` (a topic parameter or an output): expanded for the node
/// at `node_path`, then remapped.
pub fn resolve_topic(name: &str, remaps: &[(String, String)], node_path: &str) -> String {
    remap_topic(&expand_topic(name, node_path), remaps, node_path)
}

/// The topic the node subscribes to for the input topic `name` (a topic parameter, `/tf`,
/// `/clock`): expanded in the node's namespace and remapped by `-r FROM:=TO`.
pub fn input_topic(config: &Config, name: &str) -> String {
    resolve_topic(name, &config.remaps, &config.node_path())
}

/// A ROS 2 name from a fully qualified topic name.
pub fn topic_name(full: &str) -> Result<Name> {
    Name::parse(full).map_err(|e| entity("topic", full, e))
}

/// The ROS 2 package and type name of a message type (`pkg/msg/Type`).
pub fn type_name<T: RosMessage>() -> MessageTypeName {
    let package = T::TYPE.split('/').next().unwrap_or_default();
    let name = T::TYPE.rsplit('/').next().unwrap_or_default();
    MessageTypeName::new(package, name)
}

/// Parses the arguments after `--ros-args` (a further `--ros-args` is allowed, `--` ends them).
pub fn parse_ros_args(args: &[String]) -> Result<RosArgs> {
    let bad = |m: String| NodeError::RosArgs(m);
    let mut out = RosArgs::default();
    let mut it = args.iter();
    let value = |a: &str, it: &mut std::slice::Iter<String>, what: &str| {
        it.next()
            .cloned()
            .ok_or_else(|| bad(format!("{a} needs {what}")))
    };
    while let Some(a) = it.next() {
        // rcl also takes the value joined to a long option (`--remap=a:=b`).
        let (flag, joined) = match a.split_once('=') {
            Some((f, v)) if f.starts_with("--") && !f.contains(":") => (f, Some(v.to_owned())),
            _ => (a.as_str(), None),
        };
        let mut arg = |what: &str| match &joined {
            Some(v) => Ok(v.clone()),
            None => value(flag, &mut it, what),
        };
        match flag {
            "--ros-args" | "--" => {}
            "-r" | "--remap" => {
                let r = arg("FROM:=TO")?;
                let (from, to) = r
                    .split_once(":=")
                    .ok_or_else(|| bad(format!("remapping '{r}' is not FROM:=TO")))?;
                // `NODE:FROM`: a rule for one node only.
                let (node, from) = match from.split_once(':') {
                    Some((n, f)) if !n.is_empty() => (Some(n.to_owned()), f),
                    _ => (None, from),
                };
                match from {
                    "__node" | "__name" if node.is_none() => out.node = Some(to.to_owned()),
                    "__ns" if node.is_none() => out.namespace = Some(to.to_owned()),
                    _ if from.is_empty() || to.is_empty() || from.starts_with("__") => {
                        return Err(bad(format!(
                            "remapping '{r}': only __node, __ns and topic names FROM:=TO"
                        )))
                    }
                    _ => out.remaps.push((node, from.to_owned(), to.to_owned())),
                }
            }
            "-p" | "--param" => {
                let p = arg("NAME:=VALUE")?;
                out.params
                    .push(crate::config::parse_override(&p).map_err(NodeError::RosArgs)?);
            }
            "--params-file" => out.params_files.push(PathBuf::from(arg("FILE")?)),
            "--log-level" => {
                let l = arg("[NAME:=]LEVEL")?;
                let (logger, level) = match l.split_once(":=") {
                    Some((n, level)) => (Some(n.to_owned()), level),
                    None => (None, l.as_str()),
                };
                let level = log_level(level).ok_or_else(|| {
                    bad(format!(
                        "--log-level '{l}': the level is one of debug, info, warn, error, fatal, \
                         unset"
                    ))
                })?;
                if let Some(level) = level {
                    out.log_levels.push((logger, level));
                }
            }
            "-e" | "--enclave" => {
                let e = arg("ENCLAVE")?;
                validate_enclave_name("--enclave", &e).map_err(|e| bad(e.to_string()))?;
                out.enclave = Some(e);
            }
            "--log-config-file" => {
                let f = arg("FILE")?;
                out.noted.push(format!(
                    "--log-config-file {f}: ignored (the node logs to stderr; RUST_LOG and \
                     --log-level set its levels)"
                ));
            }
            "--enable-rosout-logs" => out.rosout = Some(true),
            "--disable-rosout-logs" => out.rosout = Some(false),
            "--enable-stdout-logs"
            | "--disable-stdout-logs"
            | "--enable-external-lib-logs"
            | "--disable-external-lib-logs" => out.noted.push(format!(
                "{flag}: ignored (the node logs to stderr; RUST_LOG and --log-level set its \
                 levels)"
            )),
            other => return Err(bad(format!("unsupported ROS argument '{other}'"))),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn ros_args_remap_and_set_parameters() {
        let r = parse_ros_args(&args(&[
            "--ros-args",
            "-r",
            "__node:=watch",
            "-r",
            "__ns:=/robot1",
            "-r",
            "~/speed_scaling:=/joint_trajectory_controller/speed_scaling_input",
            "-p",
            "mode:=exact",
        ]))
        .unwrap();
        assert_eq!(r.node.as_deref(), Some("watch"));
        assert_eq!(r.namespace.as_deref(), Some("/robot1"));
        assert_eq!(r.params, vec![("mode".to_string(), "exact".to_string())]);
        let remaps = r.remaps_for("watch");
        let to = "/joint_trajectory_controller/speed_scaling_input";
        assert_eq!(
            remap_topic("/robot1/watch/speed_scaling", &remaps, "/robot1/watch"),
            to
        );
        assert_eq!(
            remap_topic("/robot1/watch/min_distance", &remaps, "/robot1/watch"),
            "/robot1/watch/min_distance"
        );
        let relative = vec![("min_distance".to_string(), "d".to_string())];
        assert_eq!(
            remap_topic("/robot1/min_distance", &relative, "/robot1/watch"),
            "/robot1/d"
        );
        for bad in [
            &["-r", "__foo:=bar"][..],
            &["-r", ":=bar"],
            &["-p", "mode"],
            &["-r"],
            &["--params-file"],
            &["--log-level", "loud"],
            &["--no-such-flag"],
            &["-r", "other:__node:=x"],
        ] {
            assert!(parse_ros_args(&args(bad)).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn launch_ros_arguments_are_taken() {
        // What launch_ros builds for Node(name='watch', namespace='cell1', parameters=[file,
        // {...}], remappings=[...], ros_arguments=['--log-level', 'warn']).
        let r = parse_ros_args(&args(&[
            "--ros-args",
            "--log-level",
            "warn",
            "-r",
            "__node:=watch",
            "-r",
            "__ns:=/cell1",
            "--params-file",
            "/opt/share/ist_monitor/config/ur5e.yaml",
            "--params-file",
            "/tmp/launch_params_x",
            "-r",
            "/camera/depth/points:=/realsense/depth/points",
            "-r",
            "other_node:/joint_states:=/elsewhere",
            "--log-level",
            "cell1.watch:=DEBUG",
            "--log-level=rcl:=error",
            "--enclave",
            "/cell1",
            "--disable-rosout-logs",
        ]))
        .unwrap();
        assert_eq!(r.params_files.len(), 2);
        assert_eq!(r.params_files[1], PathBuf::from("/tmp/launch_params_x"));
        // The rule for another node is not ours.
        assert_eq!(
            r.remaps_for("watch"),
            vec![(
                "/camera/depth/points".to_string(),
                "/realsense/depth/points".to_string()
            )]
        );
        assert_eq!(r.remaps_for("other_node").len(), 2);
        // The rule naming our logger wins over the default; another logger's is not ours.
        assert_eq!(
            r.log_level_for("watch", "/cell1"),
            Some(log::LevelFilter::Debug)
        );
        assert_eq!(
            r.log_level_for("other", "/cell1"),
            Some(log::LevelFilter::Warn)
        );
        // --enclave is taken (no longer noted as ignored).
        assert_eq!(r.enclave.as_deref(), Some("/cell1"));
        assert!(r.noted.is_empty(), "{:?}", r.noted);
        assert_eq!(r.rosout, Some(false));
        // An input, expanded then remapped.
        let remaps = r.remaps_for("watch");
        assert_eq!(
            resolve_topic("/camera/depth/points", &remaps, "/cell1/watch"),
            "/realsense/depth/points"
        );
        assert_eq!(
            resolve_topic("joint_states", &remaps, "/cell1/watch"),
            "/cell1/joint_states"
        );
        assert_eq!(resolve_topic("~", &remaps, "/cell1/watch"), "/cell1/watch");
    }

    #[test]
    fn an_enclave_is_an_absolute_name() {
        assert_eq!(
            parse_ros_args(&args(&["--ros-args", "-e", "/"]))
                .unwrap()
                .enclave
                .as_deref(),
            Some("/")
        );
        for bad in ["cell1", "/cell1/", "/1cell"] {
            let e = parse_ros_args(&args(&["--ros-args", "--enclave", bad])).unwrap_err();
            assert!(e.to_string().contains(&format!("'{bad}'")), "{e}");
        }
    }

    #[test]
    fn message_type_names_follow_ros() {
        use crate::msg::{DiagnosticArray, PointCloud2};
        let t = type_name::<PointCloud2>();
        assert_eq!(t.dds_msg_type(), "sensor_msgs::msg::dds_::PointCloud2_");
        assert_eq!(
            type_name::<DiagnosticArray>().dds_msg_type(),
            "diagnostic_msgs::msg::dds_::DiagnosticArray_"
        );
    }
}
