//! SROS2 security of the node and its tools: the standard environment read as rcl reads it
//! (`ROS_SECURITY_ENABLE`, `ROS_SECURITY_STRATEGY`, `ROS_SECURITY_KEYSTORE`,
//! `ROS_SECURITY_ENCLAVE_OVERRIDE`, `--enclave`), the enclave's files checked so that a refusal
//! names the file, and the decision a node starts with ([`Security`]): on DDS, RustDDS's
//! DDS-Security 1.1 (PKI-DH authentication, signed governance and permissions, AES-GCM-GMAC)
//! with the enclave's files (`transport::context`); on zenoh, the TLS of zenoh's own config.
//!
//! Here: `environment`, the variables and the enclave's folder; `files`, the enclave's files;
//! `policy`, the decision and what the start line says of it; `error`, what stops a start.

mod environment;
mod error;
mod files;
mod policy;

pub use environment::{
    enclave_dir, request, validate_enclave_name, Request, SecurityEnv, Strategy,
};
pub use error::SecurityError;
#[cfg(feature = "security")]
pub use files::check_files;
pub use files::{first_missing, BadFile, ENCLAVE_FILES};
pub use policy::{zenoh_endpoints, Security};
