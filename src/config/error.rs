//! The one error of configuration: a file that cannot be read or parsed, or a parameter that
//! is undeclared or invalid, named so that the operator finds it in the file.

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: YAML: {message}")]
    Yaml { path: PathBuf, message: String },
    #[error("{path}: no `<node>: ros__parameters:` section")]
    NoParameters { path: PathBuf },
    #[error("parameter {0} is not declared (see `config/README.md`)")]
    Unknown(String),
    #[error("parameter {name}: {message}")]
    Invalid { name: String, message: String },
}
