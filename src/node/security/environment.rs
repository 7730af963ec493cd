//! SROS2's standard environment read as rcl reads it (rcl's `security.c`:
//! `rcl_get_security_options_from_environment`, `rcl_get_secure_root`), before any file is
//! opened. Input: the four variables and the `--enclave` argument; output: a [`Request`] —
//! security off, security asked for but nothing to use it with (Permissive only), or the
//! enclave folder to use. Constant cost: a few string tests and one `stat`.
//!
//! rcl's rules: security is on only for `ROS_SECURITY_ENABLE` exactly `true`; the strategy is
//! Enforce only for `ROS_SECURITY_STRATEGY` exactly `Enforce`, else Permissive; the enclave is
//! `ROS_SECURITY_ENCLAVE_OVERRIDE` when it is set and not empty, else `--enclave`, else `/`;
//! its folder is `<ROS_SECURITY_KEYSTORE>/enclaves` for `/` and
//! `<ROS_SECURITY_KEYSTORE>/enclaves/<name without its leading '/'>` otherwise. With Enforce,
//! an unset keystore or a missing folder is an error; with Permissive the participant starts
//! unsecured. One deviation, on the safe side: rcl validates `--enclave` but takes the override
//! as it is (and drops its first character whatever it is); here both must be absolute names,
//! so that a mistyped override is an error rather than another folder.

use std::path::{Path, PathBuf};

use super::error::SecurityError;

/// `ROS_SECURITY_STRATEGY`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strategy {
    /// Refuse to start without valid security files.
    Enforce,
    /// Start unsecured when the files are missing.
    Permissive,
}

impl Strategy {
    pub fn name(self) -> &'static str {
        match self {
            Strategy::Enforce => "Enforce",
            Strategy::Permissive => "Permissive",
        }
    }
}

/// The SROS2 variables as the process has them (`None`: unset).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SecurityEnv {
    /// `ROS_SECURITY_ENABLE`
    pub enable: Option<String>,
    /// `ROS_SECURITY_STRATEGY`
    pub strategy: Option<String>,
    /// `ROS_SECURITY_KEYSTORE`
    pub keystore: Option<String>,
    /// `ROS_SECURITY_ENCLAVE_OVERRIDE`
    pub enclave_override: Option<String>,
}

impl SecurityEnv {
    /// The variables of this process (one not valid Unicode counts as unset, as no value rcl
    /// compares it with could match it).
    pub fn from_process() -> Self {
        let var = |name: &str| std::env::var(name).ok();
        Self {
            enable: var("ROS_SECURITY_ENABLE"),
            strategy: var("ROS_SECURITY_STRATEGY"),
            keystore: var("ROS_SECURITY_KEYSTORE"),
            enclave_override: var("ROS_SECURITY_ENCLAVE_OVERRIDE"),
        }
    }

    /// Whether security is asked for: `ROS_SECURITY_ENABLE` exactly `true`.
    pub fn enabled(&self) -> bool {
        self.enable.as_deref() == Some("true")
    }

    /// The strategy: Enforce only for exactly `Enforce`.
    pub fn strategy(&self) -> Strategy {
        match self.strategy.as_deref() {
            Some("Enforce") => Strategy::Enforce,
            _ => Strategy::Permissive,
        }
    }
}

/// What the environment asks for, before the enclave's files are looked at.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    /// `ROS_SECURITY_ENABLE` is not `true`.
    Off,
    /// Permissive, and no enclave folder to use: unsecured, for the reason given.
    Unsecured { why: String },
    /// The enclave `name` (absolute), whose files are in `dir`, in `keystore`.
    Enclave {
        name: String,
        keystore: PathBuf,
        dir: PathBuf,
        strategy: Strategy,
    },
}

/// Checks that `name` is an absolute enclave name as rcl's `rcl_validate_enclave_name`
/// accepts it (a namespace's rules: `/`, or `/`-separated tokens of ASCII letters, digits and
/// `_`, none empty and none starting with a digit). `from` names where it came from.
pub fn validate_enclave_name(from: &'static str, name: &str) -> Result<(), SecurityError> {
    let bad = |why| {
        Err(SecurityError::EnclaveName {
            from,
            name: name.to_owned(),
            why,
        })
    };
    let Some(rest) = name.strip_prefix('/') else {
        return bad("it does not start with '/'");
    };
    if rest.is_empty() {
        return Ok(());
    }
    for token in rest.split('/') {
        if token.is_empty() {
            return bad("it has an empty token ('//' or a trailing '/')");
        }
        if !token.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return bad("a token holds a character other than letters, digits and '_'");
        }
        if token.starts_with(|c: char| c.is_ascii_digit()) {
            return bad("a token starts with a digit");
        }
    }
    Ok(())
}

/// The folder of enclave `name` (absolute, validated) in `keystore`, as rcl's
/// `exact_match_lookup` joins it.
pub fn enclave_dir(keystore: &Path, name: &str) -> PathBuf {
    let enclaves = keystore.join("enclaves");
    match name.strip_prefix('/') {
        Some("") | None => enclaves,
        Some(rest) => rest.split('/').fold(enclaves, |d, t| d.join(t)),
    }
}

/// What `env` asks for, with `enclave` the `--enclave` argument (`None`: not given, the root
/// enclave `/`).
pub fn request(env: &SecurityEnv, enclave: Option<&str>) -> Result<Request, SecurityError> {
    if !env.enabled() {
        return Ok(Request::Off);
    }
    let strategy = env.strategy();
    // The names are checked whatever the strategy: a malformed one is a mistake to fix.
    if let Some(e) = enclave {
        validate_enclave_name("--enclave", e)?;
    }
    let name = match env.enclave_override.as_deref().filter(|o| !o.is_empty()) {
        Some(o) => {
            validate_enclave_name("ROS_SECURITY_ENCLAVE_OVERRIDE", o)?;
            o
        }
        None => enclave.unwrap_or("/"),
    };
    let Some(keystore) = env.keystore.as_deref().filter(|k| !k.is_empty()) else {
        return match strategy {
            Strategy::Enforce => Err(SecurityError::NoKeystore),
            Strategy::Permissive => Ok(Request::Unsecured {
                why: "ROS_SECURITY_KEYSTORE is not set".into(),
            }),
        };
    };
    let keystore = PathBuf::from(keystore);
    let dir = enclave_dir(&keystore, name);
    if !dir.is_dir() {
        return match strategy {
            Strategy::Enforce => Err(SecurityError::NoEnclave {
                enclave: name.to_owned(),
                dir,
            }),
            Strategy::Permissive => Ok(Request::Unsecured {
                why: format!("enclave {name}: directory {} does not exist", dir.display()),
            }),
        };
    }
    Ok(Request::Enclave {
        name: name.to_owned(),
        keystore,
        dir,
        strategy,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(enable: &str, strategy: Option<&str>, keystore: Option<&Path>) -> SecurityEnv {
        SecurityEnv {
            enable: Some(enable.into()),
            strategy: strategy.map(String::from),
            keystore: keystore.map(|k| k.to_string_lossy().into_owned()),
            enclave_override: None,
        }
    }

    /// A keystore with the folders of `enclaves` (`/` is `enclaves/` itself).
    fn keystore(enclaves: &[&str]) -> tempfile::TempDir {
        let k = tempfile::tempdir().unwrap();
        for e in enclaves {
            std::fs::create_dir_all(enclave_dir(k.path(), e)).unwrap();
        }
        k
    }

    #[test]
    fn security_is_on_only_for_exactly_true() {
        let k = keystore(&["/"]);
        for off in ["false", "TRUE", "True", "1", "", " true"] {
            let e = env(off, Some("Enforce"), Some(k.path()));
            assert_eq!(request(&e, None).unwrap(), Request::Off, "{off:?}");
        }
        assert_eq!(
            request(&SecurityEnv::default(), Some("/x")).unwrap(),
            Request::Off
        );
        assert!(matches!(
            request(&env("true", Some("Enforce"), Some(k.path())), None).unwrap(),
            Request::Enclave { .. }
        ));
    }

    #[test]
    fn the_strategy_is_enforce_only_for_exactly_enforce() {
        for (s, want) in [
            (Some("Enforce"), Strategy::Enforce),
            (Some("enforce"), Strategy::Permissive),
            (Some("ENFORCE"), Strategy::Permissive),
            (Some("Permissive"), Strategy::Permissive),
            (Some(""), Strategy::Permissive),
            (None, Strategy::Permissive),
        ] {
            assert_eq!(env("true", s, None).strategy(), want, "{s:?}");
        }
    }

    #[test]
    fn the_enclave_folder_is_joined_as_rcl_joins_it() {
        let k = Path::new("/ks");
        assert_eq!(enclave_dir(k, "/"), PathBuf::from("/ks/enclaves"));
        assert_eq!(enclave_dir(k, "/a"), PathBuf::from("/ks/enclaves/a"));
        assert_eq!(
            enclave_dir(k, "/cell/ist_monitor"),
            PathBuf::from("/ks/enclaves/cell/ist_monitor")
        );
    }

    #[test]
    fn override_then_argument_then_root() {
        let k = keystore(&["/", "/arg", "/over"]);
        let mut e = env("true", Some("Enforce"), Some(k.path()));
        let name = |e: &SecurityEnv, arg: Option<&str>| match request(e, arg).unwrap() {
            Request::Enclave { name, dir, .. } => {
                assert_eq!(dir, enclave_dir(k.path(), &name));
                name
            }
            other => panic!("{other:?}"),
        };
        assert_eq!(name(&e, None), "/");
        assert_eq!(name(&e, Some("/arg")), "/arg");
        // An empty override is no override.
        e.enclave_override = Some(String::new());
        assert_eq!(name(&e, Some("/arg")), "/arg");
        e.enclave_override = Some("/over".into());
        assert_eq!(name(&e, Some("/arg")), "/over");
        assert_eq!(name(&e, None), "/over");
    }

    #[test]
    fn enforce_refuses_what_permissive_starts_unsecured() {
        let k = keystore(&["/there"]);
        // No keystore (unset or empty).
        for ks in [None, Some("")] {
            let mut e = env("true", Some("Enforce"), None);
            e.keystore = ks.map(String::from);
            assert!(matches!(request(&e, None), Err(SecurityError::NoKeystore)));
            e.strategy = Some("Permissive".into());
            match request(&e, None).unwrap() {
                Request::Unsecured { why } => assert!(why.contains("ROS_SECURITY_KEYSTORE")),
                other => panic!("{other:?}"),
            }
        }
        // No folder for the enclave (the root's `enclaves/` included: only /there exists).
        for enclave in [Some("/missing"), Some("/there/deeper")] {
            let e = env("true", Some("Enforce"), Some(k.path()));
            match request(&e, enclave) {
                Err(SecurityError::NoEnclave { enclave: n, dir }) => {
                    assert_eq!(Some(n.as_str()), enclave);
                    assert_eq!(dir, enclave_dir(k.path(), &n));
                }
                other => panic!("{other:?}"),
            }
            let e = env("true", None, Some(k.path()));
            match request(&e, enclave).unwrap() {
                Request::Unsecured { why } => {
                    assert!(why.contains(enclave.unwrap()) && why.contains("does not exist"))
                }
                other => panic!("{other:?}"),
            }
        }
        let e = env("true", None, Some(k.path()));
        assert_eq!(
            request(&e, Some("/there")).unwrap(),
            Request::Enclave {
                name: "/there".into(),
                keystore: k.path().to_owned(),
                dir: k.path().join("enclaves/there"),
                strategy: Strategy::Permissive,
            }
        );
    }

    #[test]
    fn enclave_names_are_absolute_ros_names_whatever_the_strategy() {
        for good in ["/", "/a", "/cell_1/ist_monitor", "/_x/Y9"] {
            validate_enclave_name("--enclave", good).unwrap();
        }
        for bad in [
            "", "a", "a/b", "/a/", "//a", "/a//b", "/1a", "/a-b", "/a b", "/ä",
        ] {
            assert!(
                validate_enclave_name("--enclave", bad).is_err(),
                "{bad:?} accepted"
            );
        }
        let k = keystore(&["/"]);
        for strategy in ["Enforce", "Permissive"] {
            let mut e = env("true", Some(strategy), Some(k.path()));
            let err = request(&e, Some("cell")).unwrap_err().to_string();
            assert!(err.contains("--enclave 'cell'"), "{err}");
            e.enclave_override = Some("cell".into());
            let err = request(&e, None).unwrap_err().to_string();
            assert!(
                err.contains("ROS_SECURITY_ENCLAVE_OVERRIDE 'cell'"),
                "{err}"
            );
        }
        // With security off nothing is looked at.
        let e = env("false", Some("Enforce"), None);
        assert_eq!(request(&e, Some("not a name")).unwrap(), Request::Off);
    }
}
