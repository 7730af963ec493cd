//! The ROS 2 command line after `--ros-args`, as far as the node takes it: `-r __node:=`,
//! `-r __ns:=`, topic remappings `FROM:=TO` (outputs), `-p NAME:=VALUE`; anything else is refused
//! naming it. Topic names expand as ROS 2 expands them (`~/x` private, `x` in the namespace, `/x`
//! absolute).

use super::{NodeError, Result};

/// The node's command-line remappings (`--ros-args -r __node:=… -r __ns:=… -r FROM:=TO -p
/// name:=value`).
#[derive(Debug, Default, Clone)]
pub struct RosArgs {
    pub node: Option<String>,
    pub namespace: Option<String>,
    /// Topic remappings, `FROM` as given (`~/x`, `x` or `/x`); they apply to the node's output
    /// topics (its inputs are parameters).
    pub remaps: Vec<(String, String)>,
    pub params: Vec<(String, String)>,
}

/// A topic name as ROS 2 expands it for the node at `node_path` (`/ns/name`): `~/x` is private
/// to the node, `x` lies in its namespace, `/x` is absolute.
pub fn expand_topic(name: &str, node_path: &str) -> String {
    let node_path = node_path.trim_end_matches('/');
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

/// Parses the arguments after `--ros-args`.
pub fn parse_ros_args(args: &[String]) -> Result<RosArgs> {
    let mut out = RosArgs::default();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--ros-args" => {}
            "-r" | "--remap" => {
                let r = it
                    .next()
                    .ok_or_else(|| NodeError::RosArgs(format!("{a} needs FROM:=TO")))?;
                let (from, to) = r.split_once(":=").ok_or_else(|| {
                    NodeError::RosArgs(format!("remapping '{r}' is not FROM:=TO"))
                })?;
                match from {
                    "__node" | "__name" => out.node = Some(to.to_owned()),
                    "__ns" => out.namespace = Some(to.to_owned()),
                    _ if from.is_empty() || to.is_empty() || from.starts_with("__") => {
                        return Err(NodeError::RosArgs(format!(
                            "remapping '{r}': only __node, __ns and topic names FROM:=TO"
                        )))
                    }
                    _ => out.remaps.push((from.to_owned(), to.to_owned())),
                }
            }
            "-p" | "--param" => {
                let p = it
                    .next()
                    .ok_or_else(|| NodeError::RosArgs(format!("{a} needs NAME:=VALUE")))?;
                out.params
                    .push(crate::config::parse_override(p).map_err(NodeError::RosArgs)?);
            }
            other => {
                return Err(NodeError::RosArgs(format!(
                    "unsupported ROS argument '{other}'"
                )))
            }
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ros_args_remap_and_set_parameters() {
        let args: Vec<String> = [
            "--ros-args",
            "-r",
            "__node:=watch",
            "-r",
            "__ns:=/robot1",
            "-r",
            "~/speed_scaling:=/joint_trajectory_controller/speed_scaling_input",
            "-p",
            "mode:=exact",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        let r = parse_ros_args(&args).unwrap();
        assert_eq!(r.node.as_deref(), Some("watch"));
        assert_eq!(r.namespace.as_deref(), Some("/robot1"));
        assert_eq!(r.params, vec![("mode".to_string(), "exact".to_string())]);
        let to = "/joint_trajectory_controller/speed_scaling_input";
        assert_eq!(
            remap_topic("/robot1/watch/speed_scaling", &r.remaps, "/robot1/watch"),
            to
        );
        assert_eq!(
            remap_topic("/robot1/watch/min_distance", &r.remaps, "/robot1/watch"),
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
            &["--enclave", "x"],
            &["-r"],
        ] {
            let bad: Vec<String> = bad.iter().map(|s| s.to_string()).collect();
            assert!(parse_ros_args(&bad).is_err(), "{bad:?}");
        }
    }
}
