//! The node's parameters on the graph, as `ros2 param` and rclpy reach them: the six
//! `rcl_interfaces` services (`~/list_parameters`, `~/get_parameters`,
//! `~/get_parameter_types`, `~/describe_parameters`, `~/set_parameters`,
//! `~/set_parameters_atomically`) and `/parameter_events`.
//!
//! Every parameter comes from the one declaration (`config::PARAMETERS`), expanded per list
//! entry (`Config::parameters`): its value, its type (read from the declared default; one
//! without a default takes the type of its value), its meaning as the description, its unit as
//! the additional constraint, `[0, ∞]` as the range of a quantity, and read-only unless it is
//! declared settable at run time.
//!
//! A set is a change of the running config (`Config::with_changes`): checked as at start (an
//! attached object also against the robot's links), refused with the reason (the parameter
//! named) or taken whole. `set_parameters` takes its
//! parameters one after the other, each its own change with its own result, as rclcpp does;
//! `set_parameters_atomically` takes them as one change (the way to add an exclusion volume
//! with its parameters). While the safety stop is raised a change that could release it is
//! refused (`Config::weakening`, from the processing thread's latest [`Safety`]). A change
//! taken is sent to the processing thread, which applies it before its next frame
//! (`Monitor::reconfigure`), and published on `/parameter_events` (new, changed and deleted
//! parameters, as rclcpp reports them).
//!
//! The services run on DDS and on zenoh (as rmw_zenoh offers services: `rmw_zenoh`), and so
//! does `/parameter_events` (`rcl_interfaces/msg/ParameterEvent`, stamped by the node's clock:
//! simulated time with `use_sim_time`, as rclcpp stamps it).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::{Arc, Mutex};

use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces as srv;
use ros2_client::ParameterValue;
use yaml_rust2::Yaml;

use super::clock::NodeClock;
use super::transport::Pub;
use super::{lock, NodeError, RosNode};
use crate::config::{Config, ParamKind, Parameter};
use crate::msg;

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
        if self.safety.stop.load(Ordering::Relaxed) {
            let in_fault = lock(&self.safety.in_fault).clone();
            let weakening = config.weakening(&new, &in_fault);
            if !weakening.is_empty() {
                return Err(format!(
                    "refused while the safety stop is raised: {} would weaken protection \
                     (set it once the stop is released)",
                    weakening.join(", ")
                ));
            }
        }
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

/// The parameter event of the change from `old` (whose parameters are `before`) to `new`
/// (stamped 0: the publisher stamps it).
fn event(old: &Config, before: &[Parameter], new: &Config) -> msg::ParameterEvent {
    let raw_of = |p: &Parameter| msg::Parameter {
        name: p.name.clone(),
        value: wire_value(ros_value(p)),
    };
    let before: BTreeMap<&str, &Parameter> = before.iter().map(|p| (p.name.as_str(), p)).collect();
    let after = new.parameters();
    let mut e = msg::ParameterEvent {
        node: old.node_path(),
        ..Default::default()
    };
    for p in &after {
        match before.get(p.name.as_str()) {
            None => e.new_parameters.push(raw_of(p)),
            Some(b) if b.value != p.value => e.changed_parameters.push(raw_of(p)),
            Some(_) => {}
        }
    }
    for b in before.values() {
        if !after.iter().any(|p| p.name == b.name) {
            e.deleted_parameters.push(raw_of(b));
        }
    }
    e
}

/// `v` as `rcl_interfaces/msg/ParameterValue` carries it (through ros2-client's wire form, which
/// the services answer with).
fn wire_value(v: ParameterValue) -> msg::ParameterValue {
    let r = raw::ParameterValue::from(v);
    msg::ParameterValue {
        kind: r.ptype,
        bool_value: r.boolean_value,
        integer_value: r.int_value,
        double_value: r.double_value,
        string_value: r.string_value,
        byte_array_value: r.byte_array,
        bool_array_value: r.bool_array,
        integer_array_value: r.int_array,
        double_array_value: r.double_array,
        string_array_value: r.string_array,
    }
}

/// A parameter's type: the declared one; for one without a default, a quantity is a double
/// (or a list of them) and anything else the value's own type (`None`).
fn kind_of(p: &Parameter) -> Option<ParamKind> {
    p.decl.kind().or_else(|| {
        p.decl.is_quantity().then_some(match p.value {
            Yaml::Array(_) => ParamKind::Doubles,
            _ => ParamKind::Double,
        })
    })
}

/// A parameter's value as ROS 2 types it: the declared type, else the value's own.
fn ros_value(p: &Parameter) -> ParameterValue {
    let number = |y: &Yaml| match y {
        Yaml::Integer(i) => Some(*i as f64),
        Yaml::Real(_) => y.as_f64(),
        _ => None,
    };
    match (&p.value, kind_of(p)) {
        (Yaml::Null, _) => ParameterValue::NotSet,
        (y, Some(ParamKind::Double)) if number(y).is_some() => {
            ParameterValue::Double(number(y).unwrap_or_default())
        }
        (Yaml::Array(a), Some(ParamKind::Doubles)) if a.iter().all(|y| number(y).is_some()) => {
            ParameterValue::DoubleArray(a.iter().filter_map(number).collect())
        }
        (Yaml::Boolean(b), _) => ParameterValue::Boolean(*b),
        (Yaml::Integer(i), _) => ParameterValue::Integer(*i),
        (Yaml::Real(_), _) => ParameterValue::Double(number(&p.value).unwrap_or(f64::NAN)),
        (Yaml::String(s), _) => ParameterValue::String(s.clone()),
        (Yaml::Array(a), _) if a.iter().all(|y| y.as_str().is_some()) => {
            ParameterValue::StringArray(
                a.iter()
                    .filter_map(|y| y.as_str().map(str::to_owned))
                    .collect(),
            )
        }
        (Yaml::Array(a), _) if a.iter().all(|y| matches!(y, Yaml::Integer(_))) => {
            ParameterValue::IntegerArray(a.iter().filter_map(Yaml::as_i64).collect())
        }
        (Yaml::Array(a), _) => {
            ParameterValue::DoubleArray(a.iter().map(|y| number(y).unwrap_or(f64::NAN)).collect())
        }
        (other, _) => ParameterValue::String(format!("{other:?}")),
    }
}

fn real(x: f64) -> Yaml {
    Yaml::Real(if x == f64::INFINITY {
        ".inf".into()
    } else if x == f64::NEG_INFINITY {
        "-.inf".into()
    } else {
        format!("{x:?}")
    })
}

/// A value set over ROS as the config's YAML, checked against the declared type (an integer
/// is taken for a double, as a file's `2` is; anything else of another type is refused
/// naming the parameter). Not set: back to the default.
fn yaml_value(name: &str, v: ParameterValue, kind: Option<ParamKind>) -> Result<Yaml, String> {
    use ParameterValue as V;
    let y = match (v, kind) {
        (V::NotSet, _) => Yaml::Null,
        (V::Boolean(b), None | Some(ParamKind::Bool)) => Yaml::Boolean(b),
        (V::Integer(i), None | Some(ParamKind::Integer)) => Yaml::Integer(i),
        (V::Integer(i), Some(ParamKind::Double)) => real(i as f64),
        (V::Double(x), None | Some(ParamKind::Double)) => real(x),
        (V::String(s), None | Some(ParamKind::String)) => Yaml::String(s),
        (V::DoubleArray(a), None | Some(ParamKind::Doubles)) => {
            Yaml::Array(a.into_iter().map(real).collect())
        }
        (V::IntegerArray(a), Some(ParamKind::Doubles)) => {
            Yaml::Array(a.into_iter().map(|i| real(i as f64)).collect())
        }
        (V::IntegerArray(a), None) => Yaml::Array(a.into_iter().map(Yaml::Integer).collect()),
        (V::StringArray(a), None | Some(ParamKind::Strings)) => {
            Yaml::Array(a.into_iter().map(Yaml::String).collect())
        }
        // An empty list comes typed as the client's YAML guessed it.
        (V::StringArray(a), Some(ParamKind::Doubles)) if a.is_empty() => Yaml::Array(Vec::new()),
        (V::DoubleArray(a), Some(ParamKind::Strings)) if a.is_empty() => Yaml::Array(Vec::new()),
        (V::IntegerArray(a), Some(ParamKind::Strings)) if a.is_empty() => Yaml::Array(Vec::new()),
        (v, kind) => {
            return Err(format!(
                "parameter {name}: expected {}, got {:?}",
                kind.map_or("a value".into(), |k| format!("{k:?}").to_lowercase()),
                v.to_parameter_type()
            ))
        }
    };
    Ok(y)
}

/// A parameter's descriptor: its type, meaning, unit, range and whether it is read-only.
fn descriptor(p: &Parameter) -> raw::ParameterDescriptor {
    let value = ros_value(p);
    let kind = kind_of(p);
    let quantity = p.decl.is_quantity();
    let mut constraints = Vec::new();
    if !p.decl.unit.is_empty() {
        constraints.push(format!("unit: {}", p.decl.unit));
    }
    constraints.push(if p.decl.settable {
        "settable at run time (checked as at start; nothing that weakens protection while the \
         safety stop is raised)"
            .to_string()
    } else {
        "read-only while the node runs".to_string()
    });
    raw::ParameterDescriptor {
        name: p.name.clone(),
        r#type: ParameterValue::to_parameter_type_raw(&value),
        description: p.decl.doc.to_owned(),
        additional_constraints: constraints.join("; "),
        read_only: !p.decl.settable,
        dynamic_typing: p.decl.kind().is_none(),
        floating_point_range: if kind == Some(ParamKind::Double) && quantity {
            vec![raw::FloatingPointRange {
                from_value: 0.0,
                to_value: f64::INFINITY,
                step: 0.0,
            }]
        } else {
            Vec::new()
        },
        integer_range: Vec::new(),
    }
}

/// The REP-2016 hashes of the six parameter services, as ROS 2 Jazzy's generated code carries
/// them (`rcl_interfaces/srv/detail/<service>__description.c`; a test reads them there): an
/// rmw_zenoh service is announced with its type's hash.
const SERVICE_HASHES: &[(&str, &str)] = &[
    (
        "ListParameters",
        "RIHS01_3e6062bfbb27bfb8730d4cef2558221f51a11646d78e7bb30a1e83afac3aad9d",
    ),
    (
        "GetParameters",
        "RIHS01_bf9803d5c74cf989a5de3e0c2e99444599a627c7ff75f97b8c05b01003675cbc",
    ),
    (
        "GetParameterTypes",
        "RIHS01_da199c878688b3e530bdfe3ca8f74cb9fa0c303101e980a9e8f260e25e1c80ca",
    ),
    (
        "DescribeParameters",
        "RIHS01_845b484d71eb0673dae682f2e3ba3c4851a65a3dcfb97bddd82c5b57e91e4cff",
    ),
    (
        "SetParameters",
        "RIHS01_56eed9a67e169f9cb6c1f987bc88f868c14a8fc9f743a263bc734c154015d7e0",
    ),
    (
        "SetParametersAtomically",
        "RIHS01_0e192ef259c07fc3c07a13191d27002222e65e00ccec653ca05e856f79285fcd",
    ),
];

/// The REP-2016 hash of parameter service `rcl_interfaces/srv/<ty>`.
pub fn service_hash(ty: &str) -> Option<&'static str> {
    SERVICE_HASHES
        .iter()
        .find(|(t, _)| *t == ty)
        .map(|(_, h)| *h)
}

/// The six services of `params` on `node` (DDS and zenoh), each answered in a task on
/// `executor`.
pub fn serve(
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    params: &Arc<Parameters>,
) -> Result<Vec<smol::Task<()>>, NodeError> {
    let mut tasks = Vec::new();
    let p = params.clone();
    tasks.extend(node.service(
        "list_parameters",
        "ListParameters",
        executor,
        move |r: srv::ListParametersRequest| srv::ListParametersResponse {
            result: p.list(&r.prefixes, r.depth),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "get_parameters",
        "GetParameters",
        executor,
        move |r: srv::GetParametersRequest| srv::GetParametersResponse {
            values: p.get(&r.names),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "get_parameter_types",
        "GetParameterTypes",
        executor,
        move |r: srv::GetParameterTypesRequest| srv::GetParameterTypesResponse {
            values: p.types(&r.names),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "describe_parameters",
        "DescribeParameters",
        executor,
        move |r: srv::DescribeParametersRequest| srv::DescribeParametersResponse {
            values: p.describe(&r.names),
        },
    )?);
    let result = |r: Result<(), String>| raw::SetParametersResult {
        successful: r.is_ok(),
        reason: r.err().unwrap_or_default(),
    };
    let p = params.clone();
    tasks.extend(node.service(
        "set_parameters",
        "SetParameters",
        executor,
        move |r: srv::SetParametersRequest| {
            srv::SetParametersResponse {
                results: r
                    .parameter
                    .iter()
                    .map(|one| result(p.set(std::slice::from_ref(one))))
                    .collect(),
            }
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "set_parameters_atomically",
        "SetParametersAtomically",
        executor,
        move |r: srv::SetParametersRequest| srv::SetParametersAtomicallyResponse {
            result: result(p.set(&r.parameter)),
        },
    )?);
    Ok(tasks)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The service hashes are ROS 2 Jazzy's: read from the generated code in the venv of the
    /// interop tests (`.ci/run` makes it; outside CI the check is left out where it is absent).
    #[test]
    fn service_hashes_are_ros_2s() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(".venv/include/rcl_interfaces/rcl_interfaces/srv/detail");
        if !dir.is_dir() {
            assert!(
                std::env::var_os("CI").is_none(),
                "CI: {} missing",
                dir.display()
            );
            eprintln!(
                "SKIPPED service_hashes_are_ros_2s: {} is absent",
                dir.display()
            );
            return;
        }
        for (ty, hash) in SERVICE_HASHES {
            let snake: String = ty
                .chars()
                .enumerate()
                .flat_map(|(i, c)| {
                    let sep = (i > 0 && c.is_ascii_uppercase()).then_some('_');
                    sep.into_iter().chain([c.to_ascii_lowercase()])
                })
                .collect();
            let text =
                std::fs::read_to_string(dir.join(format!("{snake}__description.c"))).unwrap();
            // The service's own hash: the first array after `rcl_interfaces__srv__<Ty>__get_type_hash`.
            let from = text
                .find(&format!("rcl_interfaces__srv__{ty}__get_type_hash("))
                .unwrap();
            let bytes: String = text[from..]
                .split("0x")
                .skip(1)
                .take(32)
                .map(|b| &b[..2])
                .collect();
            assert_eq!(*hash, format!("RIHS01_{bytes}"), "{ty}");
        }
    }

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

    #[test]
    fn events_name_new_changed_and_deleted_parameters() {
        let c = Config::default();
        let before = c.parameters();
        let changes: Vec<(String, Yaml)> = [
            ("exclusion_volumes", "[t]"),
            ("t.frame", "world"),
            ("t.shape", "sphere"),
            ("t.radius", "0.2"),
            ("stop_distance", "0.2"),
        ]
        .iter()
        .map(|(n, v)| {
            let y = yaml_rust2::YamlLoader::load_from_str(v).unwrap().remove(0);
            (n.to_string(), y)
        })
        .collect();
        let new = c.with_changes(&changes).unwrap();
        let e = event(&c, &before, &new);
        let names = |ps: &[msg::Parameter]| ps.iter().map(|p| p.name.clone()).collect::<Vec<_>>();
        assert!(names(&e.new_parameters).contains(&"t.radius".into()));
        assert_eq!(
            names(&e.changed_parameters),
            vec!["stop_distance", "exclusion_volumes"]
        );
        let back = new
            .with_changes(&[("exclusion_volumes".into(), Yaml::Array(vec![]))])
            .unwrap();
        let e = event(&new, &new.parameters(), &back);
        assert!(names(&e.deleted_parameters).contains(&"t.frame".into()));
    }
}
