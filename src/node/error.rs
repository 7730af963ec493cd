//! What stops the node or one of its tools, and how the node's threads share state despite a
//! panic: [`NodeError`] names the entity at fault (topic, node, argument, bag), and [`lock`]
//! takes a mutex a panicking thread left poisoned, so that the node goes on to say its last
//! word rather than panic in turn.

use std::sync::Mutex;

/// Why the node or a tool cannot run; each names the entity (topic, node, argument, bag).
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    #[error("ROS_DOMAIN_ID '{0}' is not a domain id")]
    DomainId(String),
    #[error("DDS participant: {0}")]
    Participant(String),
    /// A DDS entity that could not be made: `what` is topic, publisher, subscription, node or
    /// spinner; `message` is the DDS library's own.
    #[error("{what} {name}: {message}")]
    Entity {
        what: &'static str,
        name: String,
        message: String,
    },
    #[error("--ros-args: {0}")]
    RosArgs(String),
    #[error(transparent)]
    Bag(#[from] crate::bag::BagError),
    #[error(transparent)]
    Message(#[from] crate::msg::MsgError),
    #[error("{0}: nothing to play")]
    NothingToPlay(std::path::PathBuf),
    #[error("starting the executor thread: {0}")]
    Thread(#[from] std::io::Error),
    #[error(transparent)]
    Monitor(#[from] crate::monitor::MonitorError),
    #[error("the thread building the monitor stopped without an answer")]
    BuildLost,
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    /// SROS2: the security the environment asks for cannot be had (names the variable, the
    /// enclave or the file).
    #[error(transparent)]
    Security(#[from] super::security::SecurityError),
    /// The transport (`RMW_IMPLEMENTATION`, zenoh's session config or router).
    #[error("{0}")]
    Transport(String),
}

pub(super) type Result<T, E = NodeError> = std::result::Result<T, E>;

/// The error of an entity (`what`: topic, publisher, …) named `name` that the middleware would
/// not make, with the middleware's own message.
pub(super) fn entity(what: &'static str, name: &str, e: impl std::fmt::Debug) -> NodeError {
    NodeError::Entity {
        what,
        name: name.to_owned(),
        message: format!("{e:?}"),
    }
}

/// Locks `m`; a lock poisoned by a panicking thread still holds consistent data here (slots
/// and flags are replaced whole), so the node goes on rather than panicking in turn.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}
