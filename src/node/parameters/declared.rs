//! The node's running parameters: the config it runs with, listed, read, typed and described
//! as `ros2 param` asks, and a change checked (against the robot's links, and by
//! `parameter_changes`: while the safety stop is raised or always, against weakening
//! protection; or refused) before it goes whole to the processing thread and onto
//! `/parameter_events`.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};

use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces as srv;
use ros2_client::ParameterValue;

use super::values::{descriptor, event, ros_value, yaml_value};
use crate::config::{Config, Parameter};
use crate::msg;
use crate::node::clock::NodeClock;
use crate::node::error::lock;
use crate::node::transport::Pub;

/// What the processing thread last saw of the cell's safety: a run-time change is checked
/// against it.
#[derive(Debug)]
pub struct Safety {
    stop: AtomicBool,
    in_fault: Mutex<Vec<bool>>,
}

impl Safety {
    /// The safety stop raised (the node is not monitoring yet).
    pub fn raised() -> Self {
        Self {
            stop: AtomicBool::new(true),
            in_fault: Mutex::new(Vec::new()),
        }
    }

    pub fn set(&self, stop: bool, in_fault: Vec<bool>) {
        *lock(&self.in_fault) = in_fault;
        self.stop.store(stop, Ordering::Relaxed);
    }
}

/// The robot's links without attached objects, once it is loaded (set by the processing
/// thread): what an object may be fixed to, and what it may not be named.
pub type RobotLinks = Arc<Mutex<Option<Vec<String>>>>;

/// The node's parameters: the running config, what checks a change and where it goes.
pub struct Parameters {
    config: Mutex<Config>,
    safety: Arc<Safety>,
    robot_links: RobotLinks,
    apply: Mutex<Sender<Config>>,
    /// `/parameter_events`, and the clock that stamps its messages.
    events: Option<(Pub<msg::ParameterEvent>, Arc<NodeClock>)>,
}

impl Parameters {
    pub fn new(
        config: Config,
        safety: Arc<Safety>,
        robot_links: RobotLinks,
        apply: Sender<Config>,
        events: Option<(Pub<msg::ParameterEvent>, Arc<NodeClock>)>,
    ) -> Self {
        Self {
            config: Mutex::new(config),
            safety,
            robot_links,
            apply: Mutex::new(apply),
            events,
        }
    }

    /// Checks the attached objects of `new` that differ from `old` against the robot's links
    /// (what the build would refuse after the answer).
    fn check_objects(&self, old: &Config, new: &Config) -> Result<(), String> {
        let links = lock(&self.robot_links);
        for o in &new.attached_objects {
            if old.attached_objects.contains(o) {
                continue;
            }
            let Some(links) = links.as_ref() else {
                return Err(format!(
                    "attached object {}: the robot is not loaded yet",
                    o.name
                ));
            };
            let others = new.attached_objects.iter().filter(|a| a.name != o.name);
            if !links.contains(&o.link) && !others.clone().any(|a| a.name == o.link) {
                return Err(format!(
                    "parameter {}.link: '{}' is not a link of the robot",
                    o.name, o.link
                ));
            }
            if links.contains(&o.name) {
                return Err(format!(
                    "attached_objects: '{}' is already a link of the robot",
                    o.name
                ));
            }
        }
        Ok(())
    }

    fn find<'a>(params: &'a [Parameter], name: &str) -> Option<&'a Parameter> {
        params.iter().find(|p| p.name == name)
    }

    /// `ListParameters`: the names under `prefixes` (all with none) at most `depth` levels
    /// below them (0: any), and the prefixes of the names found, as rclcpp answers.
    pub fn list(&self, prefixes: &[String], depth: u64) -> srv::ListParametersResult {
        let params = lock(&self.config).parameters();
        let within = |rest: &str| depth == 0 || (rest.matches('.').count() as u64) < depth;
        let mut names = Vec::new();
        let mut found_prefixes: Vec<String> = Vec::new();
        for p in &params {
            let n = &p.name;
            let listed = if prefixes.is_empty() {
                within(n)
            } else {
                prefixes
                    .iter()
                    .any(|pre| n == pre || n.strip_prefix(&format!("{pre}.")).is_some_and(&within))
            };
            if listed {
                names.push(n.clone());
                if let Some((pre, _)) = n.rsplit_once('.') {
                    if !found_prefixes.iter().any(|f| f == pre) {
                        found_prefixes.push(pre.to_owned());
                    }
                }
            }
        }
        srv::ListParametersResult {
            names,
            prefixes: found_prefixes,
        }
    }

    /// `GetParameters`: each value, not set for an unknown name.
    pub fn get(&self, names: &[String]) -> Vec<raw::ParameterValue> {
        let params = lock(&self.config).parameters();
        names
            .iter()
            .map(|n| {
                Self::find(&params, n)
                    .map_or(ParameterValue::NotSet, ros_value)
                    .into()
            })
            .collect()
    }

    /// `GetParameterTypes`: each type, not set for an unknown name.
    pub fn types(&self, names: &[String]) -> Vec<u8> {
        self.get(names).iter().map(|v| v.ptype).collect()
    }

    /// `DescribeParameters`.
    pub fn describe(&self, names: &[String]) -> Vec<raw::ParameterDescriptor> {
        let params = lock(&self.config).parameters();
        names
            .iter()
            .map(|n| match Self::find(&params, n) {
                Some(p) => descriptor(p),
                None => raw::ParameterDescriptor {
                    name: n.clone(),
                    r#type: raw::ParameterType::NOT_SET,
                    description: String::new(),
                    additional_constraints: "not declared".into(),
                    read_only: true,
                    dynamic_typing: false,
                    floating_point_range: Vec::new(),
                    integer_range: Vec::new(),
                },
            })
            .collect()
    }

    /// Sets `changes` as one change: checked, then taken whole (sent to the processing thread
    /// and published as a parameter event), or refused with the reason.
    pub fn set(&self, changes: &[raw::Parameter]) -> Result<(), String> {
        let mut config = lock(&self.config);
        let params = config.parameters();
        let yaml = changes
            .iter()
            .map(|c| {
                let kind = Self::find(&params, &c.name).and_then(|p| p.decl.kind());
                // (A parameter without a default takes the type it is given.)
                yaml_value(&c.name, ParameterValue::from(c.value.clone()), kind)
                    .map(|y| (c.name.clone(), y))
            })
            .collect::<Result<Vec<_>, String>>()?;
        let new = config.with_changes(&yaml).map_err(|e| e.to_string())?;
        self.check_objects(&config, &new)?;
        let stop_raised = self.safety.stop.load(Ordering::Relaxed);
        let in_fault = lock(&self.safety.in_fault).clone();
        config.admits(&new, stop_raised, &in_fault)?;
        let mut event = event(&config, &params, &new);
        lock(&self.apply)
            .send(new.clone())
            .map_err(|_| "the node is shutting down".to_string())?;
        *config = new;
        if let Some((events, clock)) = &self.events {
            event.stamp = msg::Time::from_nanos(clock.now_ns());
            if let Err(e) = events.publish(event) {
                log::warn!("/parameter_events: {e:?}");
            }
        }
        log::info!(
            "parameters set: {}",
            changes
                .iter()
                .map(|c| c.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(overrides: &[(&str, &str)]) -> (Parameters, std::sync::mpsc::Receiver<Config>) {
        let o: Vec<(String, String)> = overrides
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        let (tx, rx) = std::sync::mpsc::channel();
        let safety = Arc::new(Safety::raised());
        safety.set(false, vec![false]);
        (
            Parameters::new(
                Config::from_overrides(&o).unwrap(),
                safety,
                Arc::new(Mutex::new(Some(vec!["base_link".into(), "tool0".into()]))),
                tx,
                None,
            ),
            rx,
        )
    }

    fn one(name: &str, value: ParameterValue) -> Vec<raw::Parameter> {
        vec![raw::Parameter {
            name: name.into(),
            value: value.into(),
        }]
    }

    #[test]
    fn every_parameter_is_listed_typed_and_described() {
        let (p, _) = params(&[]);
        let all = p.list(&[], 0);
        assert_eq!(
            all.names.len(),
            crate::config::Config::default().parameters().len()
        );
        assert!(all.prefixes.contains(&"camera".to_string()));
        let shallow = p.list(&["speed_scaling".into()], 1);
        assert!(shallow.names.contains(&"speed_scaling.human_speed".into()));
        assert!(!shallow
            .names
            .iter()
            .any(|n| n.starts_with("speed_scaling.stopping")));
        let names: Vec<String> = [
            "stop_distance",
            "release_frames",
            "camera.topic",
            "mode",
            "x",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        assert_eq!(p.types(&names), vec![3, 2, 4, 4, 0]);
        let v = p.get(&names[..1]);
        assert_eq!(v[0].double_value, 0.1);
        let d = p.describe(&names);
        assert!(!d[0].read_only && d[3].read_only);
        assert_eq!(d[0].floating_point_range[0].from_value, 0.0);
        assert!(d[0].additional_constraints.contains("unit: m"));
        assert!(d[0].description.contains("ERROR"));
    }

    #[test]
    fn a_set_is_checked_whole_and_sent_to_the_processing_thread() {
        let (p, rx) = params(&[]);
        p.set(&one("stop_distance", ParameterValue::Double(0.2)))
            .unwrap();
        assert_eq!(rx.try_recv().unwrap().stop_distance_m, 0.2);
        // An integer is taken for a double; a string is not.
        p.set(&one("warn_distance", ParameterValue::Integer(1)))
            .unwrap();
        assert_eq!(rx.try_recv().unwrap().warn_distance_m, 1.0);
        let e = p
            .set(&one("stop_distance", ParameterValue::String("0.1".into())))
            .unwrap_err();
        assert!(e.contains("stop_distance"), "{e}");
        let e = p
            .set(&one("mode", ParameterValue::String("exact".into())))
            .unwrap_err();
        assert!(e.contains("read-only"), "{e}");
        // Invalid together with the running values.
        let e = p
            .set(&one("stop_distance", ParameterValue::Double(1.5)))
            .unwrap_err();
        assert!(e.contains("warn_distance"), "{e}");
        assert!(
            rx.try_recv().is_err(),
            "nothing refused reaches the monitor"
        );
        // A volume, whole in one change.
        let mut volume = one(
            "exclusion_volumes",
            ParameterValue::StringArray(vec!["table".into()]),
        );
        volume.extend(one("table.frame", ParameterValue::String("world".into())));
        volume.extend(one(
            "table.size",
            ParameterValue::IntegerArray(vec![1, 2, 1]),
        ));
        p.set(&volume).unwrap();
        let c = rx.try_recv().unwrap();
        assert_eq!(c.exclusion_volumes[0].name, "table");
        assert_eq!(
            p.get(&["table.size".into()])[0].double_array,
            vec![1.0, 2.0, 1.0]
        );
        // Removing it while the stop is raised is taken; adding one is not.
        p.safety.set(true, vec![false]);
        p.set(&one(
            "exclusion_volumes",
            ParameterValue::StringArray(vec![]),
        ))
        .unwrap();
        let e = p.set(&volume).unwrap_err();
        assert!(e.contains("safety stop") && e.contains("table"), "{e}");
        let e = p
            .set(&one("camera.enabled", ParameterValue::Boolean(false)))
            .unwrap_err();
        assert!(e.contains("camera"), "{e}");
        p.safety.set(true, vec![true]);
        p.set(&one("camera.enabled", ParameterValue::Boolean(false)))
            .unwrap();
        // An attached object is fixed to a link of the robot and not named after one.
        p.safety.set(false, vec![false]);
        let object = |name: &str, link: &str| {
            let mut o = one(
                "attached_objects",
                ParameterValue::StringArray(vec![name.into()]),
            );
            o.extend(one(
                &format!("{name}.link"),
                ParameterValue::String(link.into()),
            ));
            o.extend(one(
                &format!("{name}.size"),
                ParameterValue::DoubleArray(vec![0.1; 3]),
            ));
            o
        };
        let e = p.set(&object("part", "flange")).unwrap_err();
        assert!(e.contains("part.link") && e.contains("flange"), "{e}");
        let e = p.set(&object("tool0", "base_link")).unwrap_err();
        assert!(e.contains("already a link"), "{e}");
        p.set(&object("part", "tool0")).unwrap();
        let last = rx.try_iter().last().unwrap();
        assert_eq!(last.attached_objects[0].link, "tool0");
    }
}
