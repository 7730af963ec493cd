//! A parameter between the config and ROS 2: its value as ROS 2 types it (the declared type,
//! else the value's own), a value set over ROS back to the config's YAML (checked against the
//! declared type), its descriptor (meaning, unit, range, read-only), and the
//! `/parameter_events` message of a change.

use std::collections::BTreeMap;

use ros2_client::parameters::raw;
use ros2_client::ParameterValue;
use yaml_rust2::Yaml;

use crate::config::{Config, ParamKind, Parameter};
use crate::msg;

/// The parameter event of the change from `old` (whose parameters are `before`) to `new`
/// (stamped 0: the publisher stamps it).
pub(super) fn event(old: &Config, before: &[Parameter], new: &Config) -> msg::ParameterEvent {
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
pub(super) fn ros_value(p: &Parameter) -> ParameterValue {
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
pub(super) fn yaml_value(
    name: &str,
    v: ParameterValue,
    kind: Option<ParamKind>,
) -> Result<Yaml, String> {
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
pub(super) fn descriptor(p: &Parameter) -> raw::ParameterDescriptor {
    let value = ros_value(p);
    let kind = kind_of(p);
    let quantity = p.decl.is_quantity();
    let mut constraints = Vec::new();
    if !p.decl.unit.is_empty() {
        constraints.push(format!("unit: {}", p.decl.unit));
    }
    if let Some(one_of) = p.decl.one_of {
        constraints.push(format!("one of {}", (one_of.names)()));
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

#[cfg(test)]
mod tests {
    use super::*;

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
