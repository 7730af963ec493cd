//! Configuration: a ROS 2 parameters file (`<node>: ros__parameters: …`, the form `ros2 run
//! --ros-args --params-file` reads), validated into a typed [`Config`]. `replay` and the live
//! node read the same files.
//!
//! Every parameter is declared once in [`PARAMETERS`] with its default, unit and meaning; a file
//! may set only declared ones (a misspelt name is an error that names it). Nested maps are
//! flattened to dotted names as ROS 2 does (`front.topic`). Names with a `<source>.` or
//! `<transform>.` prefix are declared per entry of the `sources` and `static_transforms` lists.
//! `-p name:=value` overrides (value in YAML) are applied after the file. Every value is
//! checked at load, and a bad one is an error that names the parameter.
//!
//! `params`: the declaration table. `values`: the flattened values and their typed, checked
//! accessors (a choice among an enum's names through [`crate::choice::Choice`]). `entries`: the
//! lists whose entries declare parameters. `config`: the typed [`Config`] they make, each
//! concern read by its own file: `query` (query options, thresholds, build, link selection),
//! `sources`, `poses` (static transforms, fixed joints), `shapes` (exclusion volumes, attached
//! objects), `separation` (speed and separation monitoring). `files`: parameters files as a
//! node reads them; `runtime`: a running node's parameters and their changes. `error`: the one
//! error. `choices`: the enums the parameters name a value of (source type and QoS, shapes).

mod choices;
#[allow(clippy::module_inception)]
mod config;
mod entries;
mod error;
mod files;
mod params;
mod poses;
mod query;
mod runtime;
mod separation;
mod shapes;
mod sources;
mod unobserved;
mod values;

pub use choices::{ParameterChanges, SelfShadow, SourceKind, UnobservedPolicy};
pub use config::{parse_override, Config, RobotSource};
pub use error::ConfigError;
pub use files::{key_matches, ParameterSources};
pub use params::OneOf;
pub use params::{default_of, markdown_table, ParamDecl, ParamKind, PARAMETERS};
pub use runtime::Parameter;
pub use sources::{camera_info_beside, SourceConfig, StrayFilter};
pub use unobserved::{MonitoredVolume, Unobserved};
