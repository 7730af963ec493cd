//! Why SROS2 security stops the node or a tool from starting: each error names the variable,
//! the enclave or the file at fault, so that the operator knows what to fix.

use std::path::PathBuf;

/// Why the node cannot start with the security the environment asks for.
#[derive(Debug, thiserror::Error)]
pub enum SecurityError {
    /// `--enclave` or `ROS_SECURITY_ENCLAVE_OVERRIDE` is not an absolute ROS name.
    #[error(
        "{from} '{name}' is not an enclave name: {why} (an enclave is an absolute name such as \
         /cell/ist_monitor, as rcl takes it)"
    )]
    EnclaveName {
        from: &'static str,
        name: String,
        why: &'static str,
    },
    /// Enforce, and `ROS_SECURITY_KEYSTORE` unset or empty.
    #[error(
        "SROS2: ROS_SECURITY_ENABLE=true and ROS_SECURITY_STRATEGY=Enforce, but \
         ROS_SECURITY_KEYSTORE is not set: name the keystore (tools/sros2_keystore.py makes one)"
    )]
    NoKeystore,
    /// Enforce, and the enclave's folder does not exist in the keystore.
    #[error(
        "SROS2 (Enforce): enclave {enclave}: directory {dir} does not exist (make it with \
         tools/sros2_keystore.py, or name another with --enclave or \
         ROS_SECURITY_ENCLAVE_OVERRIDE)"
    )]
    NoEnclave { enclave: String, dir: PathBuf },
    /// Enforce, and one of the enclave's six files is missing.
    #[error("SROS2 (Enforce): enclave {enclave}: {file} is missing")]
    MissingFile { enclave: String, file: PathBuf },
    /// A file of the enclave is there but unusable (either strategy: a keystore that is there
    /// and broken is a mistake to fix, not an absence to tolerate).
    #[error("SROS2: enclave {enclave}: {file}: {why}")]
    BadFile {
        enclave: String,
        file: PathBuf,
        why: String,
    },
    /// RustDDS refused the enclave's files (its own message).
    #[error("SROS2: enclave {enclave} ({dir}): the DDS security plugins refused it: {message}")]
    Refused {
        enclave: String,
        dir: PathBuf,
        message: String,
    },
    /// Enforce, in a build without the `security` feature.
    #[error(
        "SROS2 (Enforce): this ist_monitor was built without DDS security (cargo feature \
         'security', on by default): rebuild with it, or unset ROS_SECURITY_ENABLE"
    )]
    NotBuiltIn,
    /// Enforce on zenoh, whose session config has no TLS: the keystore cannot secure zenoh.
    #[error(
        "SROS2 (Enforce) on zenoh: the SROS2 keystore cannot secure zenoh (rmw_zenoh secures a \
         session through its own config), and {config} {why}: configure TLS there \
         (docs/security.md), or run on DDS"
    )]
    ZenohWithoutTls { config: String, why: String },
}
