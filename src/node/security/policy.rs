//! What a node or tool runs with, decided once at its start from the environment
//! ([`super::environment`]), the enclave's files ([`super::files`]) and the transport: off,
//! secured by an enclave (DDS) or by zenoh's own TLS, or — Permissive only — unsecured, said in
//! the start line and as a WARN. Input: the variables, `--enclave`, on zenoh its session
//! config; output: a [`Security`] or the [`SecurityError`] that stops the start. Cost: the
//! file checks, once.
//!
//! Zenoh: rmw_zenoh secures a session through its own config (TLS endpoints, certificates,
//! access control), not through the SROS2 keystore. With `ROS_SECURITY_ENABLE=true` the node
//! on zenoh therefore asks that config for TLS: every `connect` and `listen` endpoint `tls/` or
//! `quic/`. Enforce without it refuses to start; Permissive starts and says it is unsecured.

use std::path::PathBuf;

use super::environment::{request, Request, SecurityEnv, Strategy};
use super::error::SecurityError;
use super::files::first_missing;

/// The security a node runs with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Security {
    /// `ROS_SECURITY_ENABLE` is not `true`.
    Off,
    /// Asked for, Permissive, and not possible for the reason given: the node runs unsecured.
    Unsecured { why: String },
    /// DDS with the enclave `name`'s files in `dir`, of `keystore`.
    Enclave {
        name: String,
        keystore: PathBuf,
        dir: PathBuf,
    },
    /// Zenoh, secured by the TLS of its session config (`config`: where it came from).
    ZenohTls { config: String },
}

impl Security {
    /// The security of a DDS participant: `env` with `enclave` (`--enclave`; `None`: `/`).
    pub fn for_dds(env: &SecurityEnv, enclave: Option<&str>) -> Result<Self, SecurityError> {
        let (name, keystore, dir, strategy) = match request(env, enclave)? {
            Request::Off => return Ok(Security::Off),
            Request::Unsecured { why } => return Ok(Security::Unsecured { why }),
            Request::Enclave {
                name,
                keystore,
                dir,
                strategy,
            } => (name, keystore, dir, strategy),
        };
        if !cfg!(feature = "security") {
            return match strategy {
                Strategy::Enforce => Err(SecurityError::NotBuiltIn),
                Strategy::Permissive => Ok(Security::Unsecured {
                    why: "this build has no DDS security (cargo feature 'security')".into(),
                }),
            };
        }
        if let Some(file) = first_missing(&dir) {
            return match strategy {
                Strategy::Enforce => Err(SecurityError::MissingFile {
                    enclave: name,
                    file,
                }),
                Strategy::Permissive => Ok(Security::Unsecured {
                    why: format!("enclave {name}: {} is missing", file.display()),
                }),
            };
        }
        #[cfg(feature = "security")]
        let payload_protected =
            super::files::check_files(&dir).map_err(|b| SecurityError::BadFile {
                enclave: name.clone(),
                file: b.file,
                why: b.why,
            })?;
        #[cfg(feature = "security")]
        if payload_protected {
            log::warn!(
                "SROS2: enclave {name}: {} asks for payload protection (data_protection_kind \
                 ENCRYPT or SIGN), which RustDDS 0.15.1 cannot apply to samples sent in \
                 fragments: clouds on such topics will not arrive (the safety stop holds). Use \
                 metadata_protection_kind ENCRYPT with data_protection_kind NONE, which \
                 encrypts the same bytes (docs/security.md)",
                dir.join("governance.p7s").display()
            );
        }
        Ok(Security::Enclave {
            name,
            keystore,
            dir,
        })
    }

    /// The security of a zenoh session whose config (from `config`) has `endpoints` (connect
    /// and listen): the keystore plays no part.
    pub fn for_zenoh(
        env: &SecurityEnv,
        config: &str,
        endpoints: &[String],
    ) -> Result<Self, SecurityError> {
        if !env.enabled() {
            return Ok(Security::Off);
        }
        let plain: Vec<&str> = endpoints
            .iter()
            .map(String::as_str)
            .filter(|e| !(e.starts_with("tls/") || e.starts_with("quic/")))
            .collect();
        let why = if endpoints.is_empty() {
            "names no endpoint".to_owned()
        } else if !plain.is_empty() {
            format!("has endpoints without TLS ({})", plain.join(", "))
        } else {
            return Ok(Security::ZenohTls {
                config: config.to_owned(),
            });
        };
        match env.strategy() {
            Strategy::Enforce => Err(SecurityError::ZenohWithoutTls {
                config: config.to_owned(),
                why,
            }),
            Strategy::Permissive => Ok(Security::Unsecured {
                why: format!(
                    "the SROS2 keystore cannot secure zenoh and {config} {why} (docs/security.md)"
                ),
            }),
        }
    }

    /// What the start line says of it (`None`: security off, nothing to say).
    pub fn describe(&self) -> Option<String> {
        match self {
            Security::Off => None,
            Security::Unsecured { why } => Some(format!(
                "UNSECURED (ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY Permissive): {why}"
            )),
            Security::Enclave { name, keystore, .. } => Some(format!(
                "SROS2 enclave {name} (keystore {})",
                keystore.display()
            )),
            Security::ZenohTls { config } => Some(format!(
                "secured by the TLS of zenoh's {config} (the SROS2 keystore is not used on \
                 zenoh)"
            )),
        }
    }

    /// Warns when security was asked for and the node runs without it.
    pub fn warn_if_unsecured(&self, who: &str) {
        if let Security::Unsecured { why } = self {
            log::warn!(
                "{who}: SROS2 asked for (ROS_SECURITY_ENABLE=true) but not possible: {why}; \
                 running UNSECURED because ROS_SECURITY_STRATEGY is not Enforce: the peers of \
                 a secured cell will not match it, and anyone on the network can"
            );
        }
    }
}

/// The endpoints of a zenoh config's `connect/endpoints` and `listen/endpoints` values (JSON:
/// a list, or a list per mode), every string in them.
pub fn zenoh_endpoints(values: &[String]) -> Vec<String> {
    fn strings(v: &serde_json::Value, out: &mut Vec<String>) {
        match v {
            serde_json::Value::String(s) => out.push(s.clone()),
            serde_json::Value::Array(a) => a.iter().for_each(|v| strings(v, out)),
            serde_json::Value::Object(o) => o.values().for_each(|v| strings(v, out)),
            _ => {}
        }
    }
    let mut out = Vec::new();
    for value in values {
        if let Ok(v) = serde_json::from_str::<serde_json::Value>(value) {
            strings(&v, &mut out);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(strategy: &str) -> SecurityEnv {
        SecurityEnv {
            enable: Some("true".into()),
            strategy: Some(strategy.into()),
            keystore: None,
            enclave_override: None,
        }
    }

    #[test]
    fn zenoh_with_security_asks_its_config_for_tls() {
        let tls = ["tls/router:7447".to_owned(), "quic/[::]:0".to_owned()];
        let mixed = ["tls/router:7447".to_owned(), "tcp/localhost:0".to_owned()];
        let off = SecurityEnv::default();
        assert_eq!(
            Security::for_zenoh(&off, "c", &mixed).unwrap(),
            Security::Off
        );
        for s in ["Enforce", "Permissive"] {
            assert_eq!(
                Security::for_zenoh(&env(s), "c", &tls).unwrap(),
                Security::ZenohTls { config: "c".into() }
            );
        }
        let e = Security::for_zenoh(&env("Enforce"), "config x", &mixed).unwrap_err();
        assert!(
            e.to_string()
                .contains("config x has endpoints without TLS (tcp/localhost:0)"),
            "{e}"
        );
        assert!(matches!(
            Security::for_zenoh(&env("Enforce"), "c", &[]),
            Err(SecurityError::ZenohWithoutTls { .. })
        ));
        match Security::for_zenoh(&env("Permissive"), "c", &mixed).unwrap() {
            Security::Unsecured { why } => assert!(why.contains("tcp/localhost:0"), "{why}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn endpoints_are_read_from_lists_and_per_mode_lists() {
        let values = [
            r#"["tcp/localhost:7447"]"#.to_owned(),
            r#"{"router": ["tls/a:1"], "peer": ["quic/b:2"]}"#.to_owned(),
        ];
        let mut got = zenoh_endpoints(&values);
        got.sort();
        assert_eq!(got, ["quic/b:2", "tcp/localhost:7447", "tls/a:1"]);
    }

    #[test]
    fn a_missing_enclave_file_is_named_or_tolerated_by_strategy() {
        let k = tempfile::tempdir().unwrap();
        let dir = k.path().join("enclaves/cell");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("identity_ca.cert.pem"), "x").unwrap();
        let mut e = env("Enforce");
        e.keystore = Some(k.path().to_string_lossy().into_owned());
        let got = Security::for_dds(&e, Some("/cell"));
        let permissive = Security::for_dds(&env_with(&e, "Permissive"), Some("/cell"));
        if cfg!(feature = "security") {
            // The first missing in rmw_dds_common's order: cert.pem.
            let err = got.unwrap_err().to_string();
            assert!(err.contains(&format!("{} is missing", dir.join("cert.pem").display())));
            match permissive.unwrap() {
                Security::Unsecured { why } => assert!(why.contains("cert.pem is missing")),
                other => panic!("{other:?}"),
            }
        } else {
            assert!(matches!(got, Err(SecurityError::NotBuiltIn)));
            assert!(matches!(permissive, Ok(Security::Unsecured { .. })));
        }
    }

    fn env_with(e: &SecurityEnv, strategy: &str) -> SecurityEnv {
        SecurityEnv {
            strategy: Some(strategy.into()),
            ..e.clone()
        }
    }
}
