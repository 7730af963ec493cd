//! The parameters of a running node: every declared parameter expanded to the names it has in
//! this config, a change to them checked as the file was at start, and the rule for changes
//! while the safety stop is raised.
//!
//! - **Names.** A `<source>.x`, `<transform>.x`, `<volume>.x` or `<object>.x` declaration is
//!   one parameter per entry of its list (`front.enabled`, `table.size`); each has its value as
//!   given, or the declared default.
//! - **A change** is a set of (name, value) pairs, a null value meaning "back to the default".
//!   It makes a whole new config through [`Config::from_values`], with every check of a start
//!   (a new volume whose `frame` is missing, `stop_distance` above `warn_distance`: refused,
//!   naming the parameter). Only parameters declared settable may differ from the running
//!   config; a read-only one is refused by name. An entry dropped from `exclusion_volumes`
//!   takes its own parameters with it. Nothing is half-applied: the caller gets the new config
//!   or the error.
//! - **While the safety stop is raised**, a change that could release it is refused
//!   ([`Config::weakening`]): a lower `stop_distance`, `hysteresis` or `release_frames`, a
//!   stray filter that rejects more, an exclusion volume or an attached object added or
//!   changed (both leave points out), a source disabled.
//!   One exception: a source that is itself in fault may be disabled, since its fault is what
//!   holds the stop and disabling it is the operator's way to take a broken sensor out (the
//!   other sources still watch; with none left the stop holds). Raising a threshold, enabling
//!   a source and removing a volume or an object are always taken.
//! - **Who may change what** (`parameter_changes`, [`Config::admits`]): `open` applies the rule
//!   above; `strengthen_only` applies it at any time, stop raised or not, so that nobody on the
//!   network can lower a running cell's thresholds; `none` refuses every change.
//! - **A secured cell's default** ([`Config::secure_parameter_changes`]): with security asked
//!   for (`ROS_SECURITY_ENABLE=true`), `parameter_changes` not given is `strengthen_only`: TLS
//!   or SROS2 without an access list that grants `set_parameters` to the operator alone lets
//!   any holder of a certificate call the services, and where the transport ends up unsecured
//!   (Permissive) anyone can. A given `open` is kept, with a warning that names the risk.

use std::collections::{BTreeMap, BTreeSet};

use yaml_rust2::Yaml;

use super::choices::ParameterChanges;
use super::config::Config;
use super::entries::LISTS;
use super::error::ConfigError;
use super::params::{scalar_yaml, ParamDecl, PARAMETERS};
use super::values::Values;
use crate::choice::Choice;

/// One parameter of a config: its name, its declaration and its value (given, or the declared
/// default; `Yaml::Null` for none).
#[derive(Debug, Clone)]
pub struct Parameter {
    pub name: String,
    pub decl: &'static ParamDecl,
    pub value: Yaml,
}

impl Config {
    /// Every parameter of this config, in the declarations' order (each list entry's
    /// parameters in the list's order).
    pub fn parameters(&self) -> Vec<Parameter> {
        let v = Values {
            values: self.values.clone(),
        };
        let entries: BTreeMap<&str, Vec<String>> = LISTS
            .iter()
            .map(|(list, prefix)| (*prefix, v.strings(list).unwrap_or_default()))
            .collect();
        let mut out = Vec::new();
        for decl in PARAMETERS {
            let names = match LISTS
                .iter()
                .find_map(|(_, prefix)| Some((prefix, decl.name.strip_prefix(prefix)?)))
            {
                Some((prefix, rest)) => entries[prefix]
                    .iter()
                    .map(|e| format!("{e}.{rest}"))
                    .collect(),
                None => vec![decl.name.to_owned()],
            };
            for name in names {
                let value = match self.values.get(&name) {
                    Some(y) => y.clone(),
                    None => scalar_yaml(decl.default),
                };
                out.push(Parameter { name, decl, value });
            }
        }
        out
    }

    /// This config with `changes` applied (name, value; `Yaml::Null`: back to the default),
    /// checked as at start; an error names the parameter that is read-only, undeclared or
    /// invalid. The node's name, namespace and remappings are kept.
    pub fn with_changes(&self, changes: &[(String, Yaml)]) -> Result<Config, ConfigError> {
        let mut values = self.values.clone();
        for (name, value) in changes {
            match value {
                Yaml::Null => values.remove(name),
                v => values.insert(name.clone(), v.clone()),
            };
        }
        // An entry taken out of its list takes its parameters with it (unless the change sets
        // them, which is then an error naming them).
        let listed = |values: &BTreeMap<String, Yaml>| -> BTreeSet<String> {
            let v = Values {
                values: values.clone(),
            };
            LISTS
                .iter()
                .flat_map(|(list, _)| v.strings(list).unwrap_or_default())
                .collect()
        };
        let before = listed(&self.values);
        let after = listed(&values);
        let given: BTreeSet<&str> = changes.iter().map(|(n, _)| n.as_str()).collect();
        values.retain(|name, _| {
            given.contains(name.as_str())
                || !before
                    .iter()
                    .any(|e| !after.contains(e) && name.starts_with(&format!("{e}.")))
        });
        let mut new = Config::from_values(
            &self.node_name,
            &self.namespace,
            self.base.as_deref(),
            values,
        )?;
        new.remaps = self.remaps.clone();
        new.rosout = self.rosout;
        let old: BTreeMap<String, Parameter> = by_name(self.parameters());
        let now: BTreeMap<String, Parameter> = by_name(new.parameters());
        for (name, p) in old.iter().chain(now.iter()) {
            let same = old.get(name).map(|p| &p.value) == now.get(name).map(|p| &p.value);
            if !same && !p.decl.settable {
                return Err(ConfigError::Invalid {
                    name: name.clone(),
                    message: "read-only while the node runs: it is set at start (restart the \
                              node with the new value)"
                        .into(),
                });
            }
        }
        Ok(new)
    }

    /// The secure default of `parameter_changes` (see the module doc), applied at start: with
    /// `security_asked` and the parameter not given, `strengthen_only` (set as if given, so that
    /// the parameter services report it); the warning to log where `open` was given.
    pub fn secure_parameter_changes(&mut self, security_asked: bool) -> Option<String> {
        const NAME: &str = "parameter_changes";
        if !security_asked {
            return None;
        }
        if !self.values.contains_key(NAME) {
            let rule = ParameterChanges::StrengthenOnly;
            self.values
                .insert(NAME.into(), Yaml::String(rule.name().into()));
            self.parameter_changes = rule;
            return None;
        }
        (self.parameter_changes == ParameterChanges::Open).then(|| {
            "parameter_changes: open with ROS_SECURITY_ENABLE=true (given; a secured cell's \
             default is strengthen_only): anyone whose certificate the cell trusts, or anyone on \
             the network where the transport runs unsecured, may lower stop_distance, disable a \
             source or add an exclusion volume while the stop is released, unless the access \
             list grants set_parameters to the operator alone"
                .to_owned()
        })
    }

    /// Whether the running node takes `new` (a change of this config, valid on its own) while
    /// the stop is raised (`stop_raised`) or not, by `parameter_changes`; the refusal says why.
    pub fn admits(&self, new: &Config, stop_raised: bool, in_fault: &[bool]) -> Result<(), String> {
        let rule = self.parameter_changes;
        if rule == ParameterChanges::None {
            return Err(
                "refused: parameter_changes is none (the node takes no change at run \
                        time: restart it with the new parameters)"
                    .into(),
            );
        }
        if !(stop_raised || rule == ParameterChanges::StrengthenOnly) {
            return Ok(());
        }
        let weakening = self.weakening(new, in_fault);
        if weakening.is_empty() {
            return Ok(());
        }
        let when = if stop_raised {
            "while the safety stop is raised"
        } else {
            "by parameter_changes: strengthen_only"
        };
        Err(format!(
            "refused {when}: {} would weaken protection{}",
            weakening.join(", "),
            if rule == ParameterChanges::Open {
                " (set it once the stop is released)"
            } else {
                ""
            }
        ))
    }

    /// What in `new` (a change of this config) could release a raised safety stop, one line
    /// each; empty when nothing does. `in_fault[k]`: source `k` is in fault now (it may then
    /// be disabled). See the module doc.
    pub fn weakening(&self, new: &Config, in_fault: &[bool]) -> Vec<String> {
        let mut out = Vec::new();
        let mut lower = |name: &str, old: f64, new: f64| {
            if new < old {
                out.push(format!("{name} lowered from {old} to {new}"));
            }
        };
        lower("stop_distance", self.stop_distance_m, new.stop_distance_m);
        lower("hysteresis", self.hysteresis_m, new.hysteresis_m);
        lower(
            "release_frames",
            f64::from(self.release_frames),
            f64::from(new.release_frames),
        );
        lower(
            "stray_filter.cluster_radius",
            self.stray.cluster_radius_m,
            new.stray.cluster_radius_m,
        );
        let mut raise = |name: &str, old: u32, new: u32| {
            if new > old {
                out.push(format!("{name} raised from {old} to {new}"));
            }
        };
        raise(
            "stray_filter.min_points",
            self.stray.min_points,
            new.stray.min_points,
        );
        raise(
            "stray_filter.max_rejected",
            self.stray.max_rejected,
            new.stray.max_rejected,
        );
        for (k, (s, n)) in self.sources.iter().zip(&new.sources).enumerate() {
            if s.enabled && !n.enabled && !in_fault.get(k).copied().unwrap_or(false) {
                out.push(format!(
                    "source {} disabled while it is not in fault",
                    s.name
                ));
            }
        }
        for o in &new.attached_objects {
            // An object's points are the robot's: attaching one self-filters more.
            match self.attached_objects.iter().find(|a| a.name == o.name) {
                None => out.push(format!("attached object {} added", o.name)),
                Some(a) if a != o => out.push(format!("attached object {} changed", o.name)),
                Some(_) => {}
            }
        }
        for v in &new.exclusion_volumes {
            match self.exclusion_volumes.iter().find(|o| o.name == v.name) {
                None => out.push(format!("exclusion volume {} added", v.name)),
                Some(o) if o != v => out.push(format!("exclusion volume {} changed", v.name)),
                Some(_) => {}
            }
        }
        out
    }
}

fn by_name(params: Vec<Parameter>) -> BTreeMap<String, Parameter> {
    params.into_iter().map(|p| (p.name.clone(), p)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn y(text: &str) -> Yaml {
        scalar_yaml(text)
    }

    fn change(c: &Config, changes: &[(&str, &str)]) -> Result<Config, ConfigError> {
        let changes: Vec<(String, Yaml)> =
            changes.iter().map(|(n, v)| (n.to_string(), y(v))).collect();
        c.with_changes(&changes)
    }

    #[test]
    fn every_declared_parameter_is_listed_per_entry() {
        let c = Config::from_overrides(&[
            ("sources".into(), "[front, wrist]".into()),
            ("exclusion_volumes".into(), "[table]".into()),
            ("table.frame".into(), "world".into()),
            ("table.size".into(), "[1, 1, 1]".into()),
        ])
        .unwrap();
        let params = c.parameters();
        let names: Vec<&str> = params.iter().map(|p| p.name.as_str()).collect();
        for n in [
            "mode",
            "front.topic",
            "wrist.enabled",
            "table.size",
            "table.shape",
        ] {
            assert!(names.contains(&n), "{n} missing");
        }
        assert!(!names.iter().any(|n| n.starts_with('<')));
        let get = |n: &str| params.iter().find(|p| p.name == n).unwrap().value.clone();
        assert_eq!(get("table.shape"), Yaml::String("box".into()));
        assert_eq!(get("stop_distance"), y("0.1"));
        assert_eq!(get("per_link_range"), Yaml::Null);
    }

    #[test]
    fn a_change_is_checked_as_at_start_and_read_only_ones_are_refused() {
        let c = Config::default();
        let n = change(&c, &[("stop_distance", "0.2")]).unwrap();
        assert_eq!(n.stop_distance_m, 0.2);
        // Invalid together with the running values: names the parameter, changes nothing.
        let e = change(&c, &[("stop_distance", "0.5")]).unwrap_err();
        assert!(e.to_string().contains("stop_distance"), "{e}");
        // Valid at start, but read-only now.
        let e = change(&c, &[("mode", "exact")]).unwrap_err();
        assert!(
            e.to_string().contains("mode") && e.to_string().contains("read-only"),
            "{e}"
        );
        let e = change(&c, &[("no_such", "1")]).unwrap_err();
        assert!(e.to_string().contains("no_such"), "{e}");
        // A volume is added whole, and removed with its parameters.
        let e = change(&c, &[("exclusion_volumes", "[table]")]).unwrap_err();
        assert!(e.to_string().contains("table."), "{e}");
        let added = change(
            &c,
            &[
                ("exclusion_volumes", "[table]"),
                ("table.frame", "world"),
                ("table.size", "[1.0, 2.0, 0.5]"),
            ],
        )
        .unwrap();
        assert_eq!(added.exclusion_volumes.len(), 1);
        let removed = change(&added, &[("exclusion_volumes", "[]")]).unwrap();
        assert!(removed.exclusion_volumes.is_empty());
        assert!(!removed
            .parameters()
            .iter()
            .any(|p| p.name.starts_with("table.")));
        // Back to the default.
        let back = change(&n, &[("stop_distance", "~")]).unwrap();
        assert_eq!(back.stop_distance_m, 0.1);
    }

    #[test]
    fn what_could_release_a_stop_is_named() {
        let c = Config::from_overrides(&[("sources".into(), "[front, wrist]".into())]).unwrap();
        let weak = |changes: &[(&str, &str)], fault: &[bool]| {
            c.weakening(&change(&c, changes).unwrap(), fault)
        };
        assert!(weak(&[("stop_distance", "0.2")], &[false, false]).is_empty());
        assert!(weak(&[("warn_distance", "0.25")], &[false, false]).is_empty());
        assert_eq!(weak(&[("stop_distance", "0.05")], &[false, false]).len(), 1);
        assert_eq!(weak(&[("hysteresis", "0.01")], &[false, false]).len(), 1);
        assert_eq!(
            weak(&[("stray_filter.min_points", "3")], &[false, false]).len(),
            1
        );
        assert_eq!(weak(&[("front.enabled", "false")], &[false, true]).len(), 1);
        assert!(weak(&[("front.enabled", "false")], &[true, false]).is_empty());
        let volume = [
            ("exclusion_volumes", "[t]"),
            ("t.frame", "world"),
            ("t.shape", "sphere"),
            ("t.radius", "0.3"),
        ];
        assert_eq!(weak(&volume, &[false, false]).len(), 1);
        let with = change(&c, &volume).unwrap();
        let removed = change(&with, &[("exclusion_volumes", "[]")]).unwrap();
        assert!(with.weakening(&removed, &[false, false]).is_empty());
        let grown = change(&with, &[("t.radius", "0.4")]).unwrap();
        assert_eq!(with.weakening(&grown, &[false, false]).len(), 1);
        // An attached object self-filters its points: added, it weakens; removed, it does not.
        let object = [
            ("attached_objects", "[part]"),
            ("part.link", "tool0"),
            ("part.size", "[0.1, 0.1, 0.1]"),
        ];
        assert_eq!(weak(&object, &[false, false]).len(), 1);
        let held = change(&c, &object).unwrap();
        let released = change(&held, &[("attached_objects", "[]")]).unwrap();
        assert!(held.weakening(&released, &[false, false]).is_empty());
    }

    #[test]
    fn parameter_changes_decides_who_may_lower_a_threshold() {
        let rule =
            |r: &str| Config::from_overrides(&[("parameter_changes".into(), r.into())]).unwrap();
        let lower = |c: &Config| change(c, &[("stop_distance", "0.05")]).unwrap();
        let raise = |c: &Config| change(c, &[("stop_distance", "0.2")]).unwrap();
        // open: lowered while the stop is clear, refused while it is raised.
        let c = rule("open");
        assert!(c.admits(&lower(&c), false, &[]).is_ok());
        let e = c.admits(&lower(&c), true, &[]).unwrap_err();
        assert!(e.contains("while the safety stop is raised"), "{e}");
        // strengthen_only: refused at any time; raising is taken.
        let c = rule("strengthen_only");
        let e = c.admits(&lower(&c), false, &[]).unwrap_err();
        assert!(
            e.contains("strengthen_only") && e.contains("stop_distance"),
            "{e}"
        );
        assert!(c.admits(&raise(&c), false, &[]).is_ok());
        // none: every change refused, raising too.
        let c = rule("none");
        let e = c.admits(&raise(&c), false, &[]).unwrap_err();
        assert!(e.contains("parameter_changes is none"), "{e}");
        // It is set at start, never at run time.
        let c = rule("none");
        assert!(change(&c, &[("parameter_changes", "open")]).is_err());
        assert!(Config::from_overrides(&[("parameter_changes".into(), "some".into())]).is_err());
    }

    #[test]
    fn a_secured_cell_is_strengthen_only_unless_told_otherwise() {
        let given = |r: &[(&str, &str)]| {
            let o: Vec<(String, String)> = (r.iter())
                .map(|(n, v)| (n.to_string(), v.to_string()))
                .collect();
            Config::from_overrides(&o).unwrap()
        };
        let lower = |c: &Config| change(c, &[("stop_distance", "0.05")]).unwrap();
        // Security not asked for: the default stays open.
        let mut c = given(&[]);
        assert_eq!(c.secure_parameter_changes(false), None);
        assert_eq!(c.parameter_changes, ParameterChanges::Open);
        assert!(c.admits(&lower(&c), false, &[]).is_ok());
        // Asked for, not given: strengthen_only, and reported so.
        let mut c = given(&[]);
        assert_eq!(c.secure_parameter_changes(true), None);
        let e = c.admits(&lower(&c), false, &[]).unwrap_err();
        assert!(e.contains("strengthen_only"), "{e}");
        let listed = c.parameters();
        let p = listed
            .iter()
            .find(|p| p.name == "parameter_changes")
            .unwrap();
        assert_eq!(p.value, Yaml::String("strengthen_only".into()));
        // Given: kept; open with a warning that names the risk, none without.
        let mut c = given(&[("parameter_changes", "open")]);
        let w = c.secure_parameter_changes(true).unwrap();
        assert!(
            w.contains("stop_distance") && w.contains("strengthen_only"),
            "{w}"
        );
        assert!(c.admits(&lower(&c), false, &[]).is_ok());
        let mut c = given(&[("parameter_changes", "none")]);
        assert_eq!(c.secure_parameter_changes(true), None);
        assert_eq!(c.parameter_changes, ParameterChanges::None);
    }
}
