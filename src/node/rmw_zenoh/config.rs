//! The zenoh configs as rmw_zenoh reads them (the folder's **Sessions**): a node's session
//! config and the router's, each from its file or rmw_zenoh's default with
//! `ZENOH_CONFIG_OVERRIDE` on top; the check for a router when a node opens its session; and
//! the router that `ist_monitor zenoh-router` runs.

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

/// How many routers the session is connected to, by `ZENOH_ROUTER_CHECK_ATTEMPTS` (see the
/// folder's documentation, `rmw_zenoh`).
pub(super) fn check_router(session: &zenoh::Session) -> Result<usize, NodeError> {
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
                     one (rmw_zenohd, or `ist_monitor zenoh-router`) at {ZENOH_ROUTER}"
                )));
            }
            log::warn!(
                "no zenoh router connected: other nodes are found only through a router at \
                 {ZENOH_ROUTER} (rmw_zenohd, or `ist_monitor zenoh-router`) or the endpoints \
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
}
