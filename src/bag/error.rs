//! The bag readers' and writer's error: the file or folder it concerns, and what went wrong
//! (I/O, MCAP, `metadata.yaml`, one topic).

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum BagError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: MCAP: {message}")]
    Mcap { path: PathBuf, message: String },
    #[error("{path}: metadata.yaml: {message}")]
    Metadata { path: PathBuf, message: String },
    #[error("{path}: topic {topic}: {message}")]
    Topic {
        path: PathBuf,
        topic: String,
        message: String,
    },
}
