//! Parameters files as a ROS 2 node reads them with `--ros-args --params-file FILE`: each file
//! holds sections `<node key>: ros__parameters: …`, and a section applies when its key matches
//! the node's fully qualified name. Keys match as rclcpp matches them: a key without a leading
//! `/` is taken from the root (`ist_monitor` is `/ist_monitor`), `*` stands for one name (or a
//! part of one), `/**` for any number of namespaces, so `/**` matches every node and
//! `/**/ist_monitor` the node of that name in any namespace. Nested keys (`cell1: ist_monitor:
//! ros__parameters:`) join with `/`.
//!
//! Order: the sections that match apply in the order of the files and, within a file, in the
//! order they appear; a later value wins, and `-p NAME:=VALUE` wins over every file. A relative
//! path in a file (`robot_description`, `package_paths`, a mesh, `cache_dir`) is relative to
//! that file's folder, as in `--config`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use yaml_rust2::{Yaml, YamlLoader};

use super::config::Config;
use super::entries::apply_later;
use super::error::ConfigError;
use super::params::{scalar_yaml, PARAMETERS};
use super::values::flatten;

/// Whether the params-file key `key` selects the node whose fully qualified name is `fqn`.
pub fn key_matches(key: &str, fqn: &str) -> bool {
    let key = key.trim_end_matches('/');
    let key: Vec<&str> = key.trim_start_matches('/').split('/').collect();
    let fqn: Vec<&str> = fqn.trim_start_matches('/').split('/').collect();
    tokens_match(&key, &fqn)
}

fn tokens_match(key: &[&str], name: &[&str]) -> bool {
    match key.split_first() {
        None => name.is_empty(),
        Some((&"**", rest)) => (0..=name.len()).any(|skip| tokens_match(rest, &name[skip..])),
        Some((k, rest)) => name
            .split_first()
            .is_some_and(|(n, tail)| glob(k, n) && tokens_match(rest, tail)),
    }
}

/// `pattern` with `*` standing for any run of characters, against one name.
fn glob(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((head, tail)) => {
            name.starts_with(head)
                && (head.len()..=name.len())
                    .any(|i| name.is_char_boundary(i) && glob(tail, &name[i..]))
        }
    }
}

/// The sections of a parameters file, `(key, ros__parameters)` in the order they appear; nested
/// keys joined with `/`.
fn sections(path: &Path, text: &str) -> Result<Vec<(String, Yaml)>, ConfigError> {
    let docs = YamlLoader::load_from_str(text).map_err(|e| ConfigError::Yaml {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    fn walk(prefix: &str, y: &Yaml, out: &mut Vec<(String, Yaml)>) {
        let Some(h) = y.as_hash() else { return };
        for (k, v) in h {
            let Some(k) = k.as_str() else { continue };
            let key = if prefix.is_empty() {
                k.to_owned()
            } else {
                format!("{prefix}/{}", k.trim_start_matches('/'))
            };
            if !v["ros__parameters"].is_badvalue() {
                out.push((key, v["ros__parameters"].clone()));
            } else {
                walk(&key, v, out);
            }
        }
    }
    let mut out = Vec::new();
    if let Some(doc) = docs.first() {
        walk("", doc, &mut out);
    }
    if out.is_empty() {
        return Err(ConfigError::NoParameters {
            path: path.to_owned(),
        });
    }
    Ok(out)
}

/// The first section of a parameters file, `(key, ros__parameters)`: what `--config` takes.
fn first_section(path: &Path, text: &str) -> Result<(String, Yaml), ConfigError> {
    Ok(sections(path, text)?.swap_remove(0))
}

/// Whether parameter `name` (a declared name, or `<entry>.x` of a listed entry) holds a path.
fn is_path(name: &str) -> bool {
    PARAMETERS.iter().any(|d| {
        matches!(d.unit, "path" | "NAME=DIR")
            && (d.name == name
                || (d.name.starts_with('<')
                    && d.name.split_once('.').map(|(_, r)| r)
                        == name.split_once('.').map(|(_, r)| r)))
    })
}

/// `value` with a relative path made relative to `dir` (a URDF text, a `package://` URI and an
/// absolute path are left).
fn anchored(name: &str, value: Yaml, dir: &Path) -> Yaml {
    let join = |s: &str| -> String {
        let rel = !(s.starts_with('/') || s.starts_with("package://") || s.starts_with('<'));
        if rel && !s.is_empty() {
            dir.join(s).to_string_lossy().into_owned()
        } else {
            s.to_owned()
        }
    };
    match value {
        Yaml::String(s) if name == "package_paths" => Yaml::String(s),
        Yaml::String(s) => Yaml::String(join(&s)),
        Yaml::Array(items) if name == "package_paths" => Yaml::Array(
            items
                .into_iter()
                .map(|y| match y {
                    Yaml::String(s) => match s.split_once('=') {
                        Some((pkg, d)) => Yaml::String(format!("{pkg}={}", join(d))),
                        None => Yaml::String(s),
                    },
                    other => other,
                })
                .collect(),
        ),
        other => other,
    }
}

/// Where a node's parameters come from, in the order they apply.
#[derive(Debug, Default, Clone)]
pub struct ParameterSources {
    /// `--config FILE`: its first section applies whatever its key, and the key names the node
    /// unless `-r __node`/`-r __ns` do; relative paths of `-p` are taken from its folder.
    pub config: Option<PathBuf>,
    /// `--params-file FILE`, in order.
    pub params_files: Vec<PathBuf>,
    /// `-r __node:=NAME`, `-r __ns:=NS`.
    pub node: Option<String>,
    pub namespace: Option<String>,
    /// `-p NAME:=VALUE` (YAML values).
    pub overrides: Vec<(String, String)>,
}

impl Config {
    /// Reads a parameters file (its first section, whatever its key, which names the node),
    /// then applies `overrides` (`name`, YAML value).
    pub fn load(path: &Path, overrides: &[(String, String)]) -> Result<Self, ConfigError> {
        Self::parse(&read(path)?, path, overrides)
    }

    /// As [`Config::load`], from the text of the file at `path`.
    pub fn parse(
        text: &str,
        path: &Path,
        overrides: &[(String, String)],
    ) -> Result<Self, ConfigError> {
        let (key, section) = first_section(path, text)?;
        let (namespace, node_name) = key_name(&key);
        let mut values = BTreeMap::new();
        flatten("", &section, &mut values);
        let later = (overrides.iter()).map(|(name, value)| (name.clone(), scalar_yaml(value)));
        apply_later(&mut values, later);
        let base = path.parent().unwrap_or(Path::new("."));
        Self::from_values(&node_name, &namespace, Some(base), values)
    }

    /// The configuration from `sources`: the declared defaults, then `--config`'s values, then
    /// each `--params-file`'s matching sections, then `-p`. A parameters file with no section
    /// for this node is not an error (rcl skips it too) but is logged.
    pub fn from_sources(sources: &ParameterSources) -> Result<Self, ConfigError> {
        let mut values = BTreeMap::new();
        let (mut namespace, mut node) = ("/".to_owned(), "ist_monitor".to_owned());
        let mut base = PathBuf::from(".");
        if let Some(path) = &sources.config {
            let (key, section) = first_section(path, &read(path)?)?;
            (namespace, node) = key_name(&key);
            flatten("", &section, &mut values);
            base = path.parent().unwrap_or(Path::new(".")).to_owned();
        }
        if let Some(n) = &sources.node {
            node = n.clone();
        }
        if let Some(ns) = &sources.namespace {
            namespace = if ns.starts_with('/') {
                ns.clone()
            } else {
                format!("/{ns}")
            };
        }
        let fqn = format!("{}/{node}", namespace.trim_end_matches('/'));
        for path in &sources.params_files {
            let dir = path.parent().unwrap_or(Path::new("."));
            let mut matched = false;
            for (key, section) in sections(path, &read(path)?)? {
                if !key_matches(&key, &fqn) {
                    continue;
                }
                matched = true;
                let mut file_values = BTreeMap::new();
                flatten("", &section, &mut file_values);
                let later = file_values.into_iter().map(|(name, value)| {
                    let value = if is_path(&name) {
                        anchored(&name, value, dir)
                    } else {
                        value
                    };
                    (name, value)
                });
                apply_later(&mut values, later);
            }
            if !matched {
                log::warn!(
                    "{}: no section for node {fqn} (keys are node names such as {fqn}, \
                     {node} or /**): nothing taken from it",
                    path.display()
                );
            }
        }
        let later = (sources.overrides.iter()).map(|(n, value)| (n.clone(), scalar_yaml(value)));
        apply_later(&mut values, later);
        Self::from_values(&node, &namespace, Some(&base), values)
    }
}

fn read(path: &Path) -> Result<String, ConfigError> {
    std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
        path: path.to_owned(),
        source,
    })
}

/// The namespace and node name a `--config` file's key gives (`/ns/name`; `/**` and other
/// patterns name the node `ist_monitor` at the root).
fn key_name(key: &str) -> (String, String) {
    if key.contains('*') {
        return ("/".to_owned(), "ist_monitor".to_owned());
    }
    match key.trim_start_matches('/').rsplit_once('/') {
        Some((ns, name)) => (format!("/{ns}"), name.to_owned()),
        None => ("/".to_owned(), key.trim_start_matches('/').to_owned()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_match_as_rclcpp_matches_them() {
        for (key, fqn, expected) in [
            ("/**", "/ist_monitor", true),
            ("/**", "/cell1/arm/ist_monitor", true),
            ("ist_monitor", "/ist_monitor", true),
            ("/ist_monitor", "/ist_monitor", true),
            ("ist_monitor", "/cell1/ist_monitor", false),
            ("/cell1/ist_monitor", "/cell1/ist_monitor", true),
            ("/cell1/*", "/cell1/ist_monitor", true),
            ("/cell1/*", "/cell1/arm/ist_monitor", false),
            ("/**/ist_monitor", "/ist_monitor", true),
            ("/**/ist_monitor", "/a/b/ist_monitor", true),
            ("/**/ist_monitor", "/a/b/other", false),
            ("/cell*/ist_*", "/cell2/ist_monitor", true),
            ("/cell2/ist_monitor", "/cell1/ist_monitor", false),
        ] {
            assert_eq!(key_matches(key, fqn), expected, "{key} against {fqn}");
        }
    }

    /// An entry that `-p` (or a later params file) takes out of its list leaves its parameters
    /// out, as the running node does (the loader once refused `-p exclusion_volumes:=[]` with
    /// "floor.frame is not declared"); a typo in the list, or a name under no entry, is still
    /// refused.
    #[test]
    fn an_entry_taken_out_of_its_list_leaves_its_parameters_out() {
        let dir = tempfile::tempdir().unwrap();
        let file = write(
            dir.path(),
            "cell.yaml",
            "ist_monitor:\n  ros__parameters:\n    robot_description: arm.urdf\n    \
             exclusion_volumes: [floor]\n    floor:\n      frame: world\n      \
             size: [2.0, 2.0, 0.02]\n",
        );
        let load = |o: &[(&str, &str)]| {
            let o: Vec<(String, String)> = (o.iter())
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect();
            Config::load(&file, &o)
        };
        assert_eq!(load(&[]).unwrap().exclusion_volumes.len(), 1);
        let none = load(&[("exclusion_volumes", "[]")]).unwrap();
        assert!(none.exclusion_volumes.is_empty());
        let e = load(&[("exclusion_volumes", "[flor]")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("parameter flor."), "{e}");
        let e = load(&[("exclusion_volumes", "[]"), ("flor.frame", "world")])
            .unwrap_err()
            .to_string();
        assert!(e.contains("flor.frame is not declared"), "{e}");
        // A later params file takes the list as `-p` does.
        let later = write(
            dir.path(),
            "later.yaml",
            "/**:\n  ros__parameters:\n    exclusion_volumes: []\n",
        );
        let sources = ParameterSources {
            config: Some(file.clone()),
            params_files: vec![later],
            ..ParameterSources::default()
        };
        assert!(Config::from_sources(&sources)
            .unwrap()
            .exclusion_volumes
            .is_empty());
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn files_apply_in_order_and_p_wins() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("share");
        std::fs::create_dir(&sub).unwrap();
        // A package's file, with a relative robot path and sections for other nodes.
        let a = write(
            &sub,
            "a.yaml",
            "other_node:\n  ros__parameters:\n    mode: fast\n\
             /**:\n  ros__parameters:\n    mode: exact\n    warn_distance: 0.5\n    robot_description: robot.urdf\n    package_paths: [arm=meshes]\n\
             /cell1/watch:\n  ros__parameters:\n    stop_distance: 0.2\n",
        );
        // What launch_ros writes for a dict: the node's full name as key, lists tagged as
        // Python tuples.
        let b = write(
            dir.path(),
            "launch_params_x",
            "/cell1/watch:\n  ros__parameters:\n    warn_distance: 0.6\n    links: !!python/tuple\n    - link1\n    - link2\n",
        );
        let c = Config::from_sources(&ParameterSources {
            params_files: vec![a.clone(), b.clone()],
            node: Some("watch".into()),
            namespace: Some("cell1".into()),
            overrides: vec![("stop_distance".into(), "0.25".into())],
            ..Default::default()
        })
        .unwrap();
        assert_eq!(c.node_path(), "/cell1/watch");
        assert_eq!(c.query.mode, crate::query::Mode::Exact);
        assert_eq!(c.warn_distance_m, 0.6);
        assert_eq!(c.stop_distance_m, 0.25);
        assert_eq!(
            c.selection.include,
            vec!["link1".to_string(), "link2".to_string()]
        );
        assert_eq!(
            c.robot_description,
            Some(crate::config::RobotSource::File(sub.join("robot.urdf")))
        );
        assert_eq!(c.package_paths[0].dir, sub.join("meshes"));
        // Another node in another namespace takes only the wildcard section.
        let c = Config::from_sources(&ParameterSources {
            params_files: vec![a, b],
            ..Default::default()
        })
        .unwrap();
        assert_eq!(c.node_path(), "/ist_monitor");
        assert_eq!(c.warn_distance_m, 0.5);
        assert_eq!(c.stop_distance_m, 0.1);
        // A misspelt parameter in a matching section names itself; a missing file names it.
        let bad = write(
            dir.path(),
            "bad.yaml",
            "/**:\n  ros__parameters:\n    warn_distanse: 1\n",
        );
        let error = |file: PathBuf| {
            Config::from_sources(&ParameterSources {
                params_files: vec![file],
                ..Default::default()
            })
            .unwrap_err()
            .to_string()
        };
        let e = error(bad);
        assert!(e.contains("warn_distanse"), "{e}");
        let e = error(dir.path().join("missing.yaml"));
        assert!(e.contains("missing.yaml"), "{e}");
    }
}
