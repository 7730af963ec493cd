//! `ist_monitor record`: the node's outputs (`~/min_distance`, `~/link_distances`,
//! `~/safety_stop`, `/diagnostics`) received from DDS and written to an MCAP, each at its
//! receive time, for tests and for looking at a live node afterwards.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::Result;
use futures::StreamExt;
use serde::de::DeserializeOwned;

use super::{subscription, tool_node, RELIABLE_QOS};
use crate::bag::{writer::Compression, BagWriter};
use crate::msg::{Bool, DiagnosticArray, Float64, JointState, RosMessage};

/// Records the outputs of the node `node` (`/ns/name`) for `duration_s` into `out`.
pub fn record(node_path: &str, out: &Path, duration_s: f64) -> Result<usize> {
    let executor = smol::Executor::new();
    let (_ctx, mut node) = tool_node("ist_monitor_record", &executor)?;
    let writer = Arc::new(Mutex::new(Some(BagWriter::create(out, Compression::Zstd)?)));
    let count = Arc::new(Mutex::new(0usize));
    let base = node_path.trim_end_matches('/');
    fn subscribe<T: RosMessage + DeserializeOwned + Send + Sync + 'static>(
        node: &mut ros2_client::Node,
        executor: &smol::Executor<'static>,
        topic: String,
        writer: Arc<Mutex<Option<BagWriter>>>,
        count: Arc<Mutex<usize>>,
    ) -> Result<()> {
        let sub = subscription::<T>(node, &topic, RELIABLE_QOS)?;
        executor
            .spawn(async move {
                let mut stream = std::pin::pin!(sub.async_stream());
                while let Some(Ok((m, _))) = stream.next().await {
                    let now = SystemTime::now()
                        .duration_since(UNIX_EPOCH)
                        .map_or(0, |d| d.as_nanos() as u64);
                    if let Some(w) = writer.lock().expect("writer").as_mut() {
                        if let Err(e) = w.write(&topic, now, &m) {
                            log::warn!("{e}");
                        }
                        *count.lock().expect("count") += 1;
                    }
                }
            })
            .detach();
        Ok(())
    }
    let ex: &'static smol::Executor<'static> = Box::leak(Box::new(executor));
    subscribe::<Float64>(
        &mut node,
        ex,
        format!("{base}/min_distance"),
        writer.clone(),
        count.clone(),
    )?;
    subscribe::<JointState>(
        &mut node,
        ex,
        format!("{base}/link_distances"),
        writer.clone(),
        count.clone(),
    )?;
    subscribe::<Bool>(
        &mut node,
        ex,
        format!("{base}/safety_stop"),
        writer.clone(),
        count.clone(),
    )?;
    subscribe::<DiagnosticArray>(
        &mut node,
        ex,
        "/diagnostics".into(),
        writer.clone(),
        count.clone(),
    )?;
    smol::block_on(ex.run(smol::Timer::after(Duration::from_secs_f64(duration_s))));
    drop(node);
    smol::block_on(ex.run(smol::Timer::after(Duration::from_millis(50))));
    let w = writer.lock().expect("writer").take();
    if let Some(w) = w {
        w.finish()?;
    }
    let n = *count.lock().expect("count");
    Ok(n)
}
