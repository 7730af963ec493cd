//! Why the GPU backend could not be made or gave up a query: no adapter or device, a tree the
//! shader cannot walk, a buffer past the device's limits, a failed readback. Every one sends the
//! query (or every query) to the CPU.

use crate::query::layout::GPU_STACK;

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("GPU device: {0}")]
    Device(String),
    #[error("link {link}: tree depth needs more than the shader's stack of {GPU_STACK}")]
    TooDeep { link: String },
    #[error("link {link}: node {node} of a tree no descent can walk (empty, more children than the tree's branching, or a child outside its arrays or before its parent)")]
    BadTree { link: String, node: usize },
    #[error("{0} bytes exceed the device's storage buffer limit")]
    TooLarge(u64),
    #[error("reading back: {0}")]
    Readback(String),
}
