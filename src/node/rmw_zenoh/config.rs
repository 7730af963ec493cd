//! The zenoh configs as rmw_zenoh reads them (the folder's **Sessions**): a node's session
//! config and the router's, each from its file or rmw_zenoh's default with
//! `ZENOH_CONFIG_OVERRIDE` on top; the check of the TLS files a config names (before zenoh
//! opens them, whose own error names neither the key nor the file); the check for a router
//! when a node opens its session; and the router that `ist_monitor zenoh-router` runs.

use std::path::Path;
use std::time::{Duration, Instant};

use zenoh::Wait;

use crate::node::error::NodeError;

/// rmw_zenoh's router endpoint.
pub const ZENOH_ROUTER: &str = "tcp/localhost:7447";

/// Sets `key` to the JSON5 `value` in `config`; an error names `what` config and the key.
fn set_json5(
    config: &mut zenoh::Config,
    what: &str,
    key: &str,
    value: &str,
) -> Result<(), NodeError> {
    config
        .insert_json5(key, value)
        .map_err(|e| NodeError::Transport(format!("{what} {key}: {e}")))
}

/// A zenoh config of these keys set, over zenoh's defaults.
fn zenoh_config(what: &str, keys: &[(&str, String)]) -> Result<zenoh::Config, NodeError> {
    let mut c = zenoh::Config::default();
    for (key, value) in keys {
        set_json5(&mut c, what, key, value)?;
    }
    Ok(c)
}

/// rmw_zenoh's default session config of a node (see the folder's documentation, `rmw_zenoh`).
fn rmw_zenoh_default_config() -> Result<zenoh::Config, NodeError> {
    zenoh_config(
        "zenoh config",
        &[
            ("mode", "\"peer\"".into()),
            ("connect/endpoints", format!("[\"{ZENOH_ROUTER}\"]")),
            ("listen/endpoints", "[\"tcp/localhost:0\"]".into()),
            ("scouting/multicast/enabled", "false".into()),
            ("scouting/gossip/enabled", "true".into()),
            // Samples are timestamped: a transient-local cache orders by them.
            ("timestamping/enabled", "true".into()),
        ],
    )
}

/// Which zenoh config: a node's session, or the router's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigFor {
    Session,
    Router,
}

impl ConfigFor {
    /// The variable that names its config file, as rmw_zenoh reads it.
    pub fn uri_variable(self) -> &'static str {
        match self {
            ConfigFor::Session => "ZENOH_SESSION_CONFIG_URI",
            ConfigFor::Router => "ZENOH_ROUTER_CONFIG_URI",
        }
    }
}

/// A config by rmw_zenoh's rules, and where it came from: the file named by `uri` (the value of
/// [`ConfigFor::uri_variable`]), else rmw_zenoh's default (a node's: see the folder's
/// documentation; the router's: listens on [`ZENOH_ROUTER`], no multicast scouting), then the
/// `key=value;…` entries of `overrides` (`ZENOH_CONFIG_OVERRIDE`) on top.
pub fn rmw_zenoh_config(
    what: ConfigFor,
    uri: Option<&str>,
    overrides: Option<&str>,
) -> Result<(zenoh::Config, String), NodeError> {
    let (mut config, mut from) = match uri.map(str::trim).filter(|u| !u.is_empty()) {
        Some(uri) => (
            zenoh::Config::from_file(uri)
                .map_err(|e| NodeError::Transport(format!("{} {uri}: {e}", what.uri_variable())))?,
            format!("config {uri} ({})", what.uri_variable()),
        ),
        None => match what {
            ConfigFor::Session => (
                rmw_zenoh_default_config()?,
                format!("rmw_zenoh's default session config (router at {ZENOH_ROUTER})"),
            ),
            ConfigFor::Router => (
                zenoh_config(
                    "zenoh router config",
                    &[
                        ("mode", "\"router\"".into()),
                        ("listen/endpoints", format!("[\"{ZENOH_ROUTER}\"]")),
                        ("scouting/multicast/enabled", "false".into()),
                        ("timestamping/enabled", "true".into()),
                    ],
                )?,
                format!("rmw_zenoh's default router config ({ZENOH_ROUTER})"),
            ),
        },
    };
    if let Some(overrides) = overrides {
        for entry in overrides
            .split(';')
            .map(str::trim)
            .filter(|s| !s.is_empty())
        {
            let (key, value) = entry.split_once('=').ok_or_else(|| {
                NodeError::Transport(format!("ZENOH_CONFIG_OVERRIDE: '{entry}' is not key=value"))
            })?;
            set_json5(
                &mut config,
                "ZENOH_CONFIG_OVERRIDE",
                key.trim(),
                value.trim(),
            )?;
        }
        from.push_str(&format!(", with ZENOH_CONFIG_OVERRIDE '{overrides}'"));
    }
    Ok((config, from))
}

/// [`rmw_zenoh_config`] from the environment.
pub fn config_from_env(what: ConfigFor) -> Result<(zenoh::Config, String), NodeError> {
    let uri = std::env::var(what.uri_variable()).ok();
    let overrides = std::env::var("ZENOH_CONFIG_OVERRIDE").ok();
    rmw_zenoh_config(what, uri.as_deref(), overrides.as_deref())
}

/// The TLS files a config may name (`transport/link/tls/<key>`), each a path to a PEM file.
const TLS_FILES: [&str; 5] = [
    "root_ca_certificate",
    "listen_certificate",
    "listen_private_key",
    "connect_certificate",
    "connect_private_key",
];

/// Checks that every TLS file `config` names can be read, so that a missing or unreadable
/// certificate or key is an error naming its key and path (relative paths are read from the
/// working directory, as zenoh reads them) instead of zenoh's "unable to connect". `from` says
/// where the config came from. Costs one `open` per named file.
pub fn check_tls_files(config: &zenoh::Config, from: &str) -> Result<(), NodeError> {
    for key in TLS_FILES {
        let key = format!("transport/link/tls/{key}");
        let Ok(value) = config.get_json(&key) else {
            continue;
        };
        let Ok(Some(path)) = serde_json::from_str::<Option<String>>(&value) else {
            continue;
        };
        if let Err(e) = std::fs::File::open(&path) {
            let cwd = std::env::current_dir()
                .map(|d| format!(" (relative to {})", d.display()))
                .unwrap_or_default();
            let cwd = if Path::new(&path).is_relative() {
                cwd
            } else {
                String::new()
            };
            return Err(NodeError::Transport(format!(
                "{key} '{path}'{cwd} of the {from}: {e}"
            )));
        }
    }
    Ok(())
}

/// How many routers the session is connected to, by `ZENOH_ROUTER_CHECK_ATTEMPTS` (see the
/// folder's documentation, `rmw_zenoh`); `endpoints` are those the session's config connects
/// to, for the messages.
pub(super) fn check_router(session: &zenoh::Session, endpoints: &str) -> Result<usize, NodeError> {
    let count = || session.info().routers_zid().wait().count();
    let attempts: i64 = match std::env::var("ZENOH_ROUTER_CHECK_ATTEMPTS") {
        Ok(v) => v.trim().parse().map_err(|_| {
            NodeError::Transport(format!(
                "ZENOH_ROUTER_CHECK_ATTEMPTS '{v}' is not an integer"
            ))
        })?,
        Err(_) => 0,
    };
    if attempts < 0 {
        return Ok(count());
    }
    let deadline = Instant::now() + Duration::from_secs(attempts as u64);
    loop {
        let n = count();
        if n > 0 {
            return Ok(n);
        }
        if Instant::now() >= deadline {
            if attempts > 0 {
                return Err(NodeError::Transport(format!(
                    "no zenoh router after {attempts} s (ZENOH_ROUTER_CHECK_ATTEMPTS): start \
                     one (rmw_zenohd, or `ist_monitor zenoh-router`) at {endpoints}"
                )));
            }
            log::warn!(
                "no zenoh router connected: other nodes are found only through a router at \
                 {endpoints} (rmw_zenohd, or `ist_monitor zenoh-router`) or the endpoints \
                 the session config names (docs/node.md)"
            );
            return Ok(0);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// A zenoh router, as `rmw_zenohd` runs one for ROS 2: its config by rmw_zenoh's rules
/// (`ZENOH_ROUTER_CONFIG_URI`, else listening on [`ZENOH_ROUTER`] without multicast scouting;
/// `ZENOH_CONFIG_OVERRIDE` on top), `listen` replacing its endpoints where given. It introduces
/// the peers that connect to it to each other. Runs until `stop` is set.
pub fn zenoh_router(
    listen: Option<&str>,
    stop: &std::sync::atomic::AtomicBool,
) -> Result<(), NodeError> {
    let (mut c, from) = config_from_env(ConfigFor::Router)?;
    if let Some(listen) = listen {
        set_json5(
            &mut c,
            "zenoh router config",
            "listen/endpoints",
            &format!("[\"{listen}\"]"),
        )?;
    }
    let endpoints = c.get_json("listen/endpoints").unwrap_or_default();
    check_tls_files(&c, &format!("zenoh router ({from})"))?;
    let session = zenoh::open(c)
        .wait()
        .map_err(|e| NodeError::Transport(format!("zenoh router on {endpoints} ({from}): {e}")))?;
    log::info!(
        "zenoh router {} listening on {endpoints} ({from})",
        session.zid()
    );
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = session.close().wait();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_session_config_is_rmw_zenohs() {
        let c = rmw_zenoh_default_config().unwrap();
        let connect = c.get_json("connect/endpoints").unwrap();
        assert!(connect.contains("tcp/localhost:7447"), "{connect}");
        assert_eq!(c.get_json("scouting/multicast/enabled").unwrap(), "false");
    }

    #[test]
    fn configs_follow_rmw_zenohs_variables() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("router.json5");
        std::fs::write(
            &file,
            r#"{ mode: "router", listen: { endpoints: ["tcp/127.0.0.1:7455"] } }"#,
        )
        .unwrap();
        let (c, from) =
            rmw_zenoh_config(ConfigFor::Router, Some(file.to_str().unwrap()), None).unwrap();
        assert!(c.get_json("listen/endpoints").unwrap().contains("7455"));
        assert!(from.contains("ZENOH_ROUTER_CONFIG_URI"), "{from}");
        let (c, _) = rmw_zenoh_config(ConfigFor::Router, None, None).unwrap();
        assert!(c.get_json("listen/endpoints").unwrap().contains("7447"));
        assert_eq!(c.get_json("mode").unwrap(), "\"router\"");
        let (c, from) = rmw_zenoh_config(
            ConfigFor::Session,
            Some("  "),
            Some("connect/endpoints=[\"tcp/127.0.0.1:7450\"]; scouting/gossip/enabled=false"),
        )
        .unwrap();
        assert!(c.get_json("connect/endpoints").unwrap().contains("7450"));
        assert_eq!(c.get_json("scouting/gossip/enabled").unwrap(), "false");
        assert!(from.contains("default session config"), "{from}");
        // A missing file and a malformed override are errors that name the variable.
        let e = rmw_zenoh_config(ConfigFor::Session, Some("/nonexistent.json5"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("ZENOH_SESSION_CONFIG_URI"), "{e}");
        let e = rmw_zenoh_config(ConfigFor::Router, None, Some("mode"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("ZENOH_CONFIG_OVERRIDE"), "{e}");
    }

    /// The shipped secure configs are valid zenoh configs by rmw_zenoh's rules: the router
    /// listens on TLS only, with mTLS and a deny-by-default access control; the session is a
    /// TLS client; and the TLS files they name are checked (relative to the working directory).
    #[test]
    fn the_secure_configs_parse_and_their_tls_files_are_checked() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/zenoh");
        let router = root.join("secure_router.json5");
        let (c, from) =
            rmw_zenoh_config(ConfigFor::Router, Some(router.to_str().unwrap()), None).unwrap();
        assert_eq!(
            c.get_json("listen/endpoints").unwrap(),
            r#"["tls/localhost:7447"]"#
        );
        assert_eq!(
            c.get_json("transport/link/tls/enable_mtls").unwrap(),
            "true"
        );
        assert_eq!(c.get_json("access_control/enabled").unwrap(), "true");
        assert_eq!(
            c.get_json("access_control/default_permission").unwrap(),
            "\"deny\""
        );
        // Run elsewhere than beside certs/: the missing file is named, with its key.
        let e = check_tls_files(&c, &from).unwrap_err().to_string();
        assert!(
            e.contains("transport/link/tls/root_ca_certificate 'certs/ca.pem'")
                && e.contains("relative to")
                && e.contains("secure_router.json5"),
            "{e}"
        );
        let session = root.join("secure_session.json5");
        let (c, from) =
            rmw_zenoh_config(ConfigFor::Session, Some(session.to_str().unwrap()), None).unwrap();
        assert_eq!(c.get_json("mode").unwrap(), "\"client\"");
        assert_eq!(
            c.get_json("connect/endpoints").unwrap(),
            r#"["tls/localhost:7447"]"#
        );
        assert!(check_tls_files(&c, &from).is_err());
        // With the files present (absolute paths, as an override gives them) the check passes;
        // one unreadable file is named.
        let dir = tempfile::tempdir().unwrap();
        let mut overrides = String::new();
        for (key, file) in [
            ("root_ca_certificate", "ca.pem"),
            ("connect_certificate", "me.pem"),
            ("connect_private_key", "me.key"),
        ] {
            let path = dir.path().join(file);
            std::fs::write(&path, "PEM").unwrap();
            overrides.push_str(&format!("transport/link/tls/{key}=\"{}\";", path.display()));
        }
        let (c, from) = rmw_zenoh_config(
            ConfigFor::Session,
            Some(session.to_str().unwrap()),
            Some(&overrides),
        )
        .unwrap();
        check_tls_files(&c, &from).unwrap();
        std::fs::remove_file(dir.path().join("me.key")).unwrap();
        let e = check_tls_files(&c, &from).unwrap_err().to_string();
        assert!(
            e.contains("connect_private_key") && e.contains("me.key") && !e.contains("relative"),
            "{e}"
        );
        // rmw_zenoh's default names no TLS file.
        let (c, from) = rmw_zenoh_config(ConfigFor::Session, None, None).unwrap();
        check_tls_files(&c, &from).unwrap();
    }
}
