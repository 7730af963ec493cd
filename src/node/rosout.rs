//! `/rosout`: the node's log on the graph, as rcl publishes a node's log (`rcl_interfaces/msg/Log`,
//! reliable, transient local, the last 1000 kept for 10 s), so that `rqt_console`, `ros2 topic
//! echo /rosout` and a bag recorder see why the node says what it says. [`RosoutLog`] is the
//! process's logger: it writes every record to stderr through the logger it wraps, and hands the
//! node's own records (target `ist_monitor…`) to a thread that publishes them, once the node has
//! started one ([`forward`]). The hand-over never blocks a logging thread: with the queue full a
//! line is left out of `/rosout` (it is still on stderr), and the publishing thread itself logs
//! nothing, so a record can never loop back.

use std::sync::mpsc::{sync_channel, SyncSender};
use std::sync::{Mutex, OnceLock};

use super::error::lock;
use super::transport::Pub;
use crate::msg::{Log, Time};

/// Lines waiting for the publishing thread.
const QUEUE: usize = 1000;

/// The process's logger: stderr (the wrapped logger) and `/rosout`.
pub struct RosoutLog {
    inner: Box<dyn log::Log>,
    /// The publishing thread's queue and the node's logger name, while a node forwards.
    to: Mutex<Option<(SyncSender<Log>, String)>>,
}

static LOGGER: OnceLock<&'static RosoutLog> = OnceLock::new();

/// Installs the process's logger: `inner` (stderr) with `max`, and `/rosout` once a node
/// forwards.
pub fn install(inner: Box<dyn log::Log>, max: log::LevelFilter) -> Result<(), log::SetLoggerError> {
    let logger: &'static RosoutLog = Box::leak(Box::new(RosoutLog {
        inner,
        to: Mutex::new(None),
    }));
    log::set_logger(logger)?;
    log::set_max_level(max);
    let _ = LOGGER.set(logger);
    Ok(())
}

fn level(l: log::Level) -> u8 {
    match l {
        log::Level::Error => Log::ERROR,
        log::Level::Warn => Log::WARN,
        log::Level::Info => Log::INFO,
        log::Level::Debug | log::Level::Trace => Log::DEBUG,
    }
}

impl log::Log for RosoutLog {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        self.inner.enabled(metadata)
    }

    fn log(&self, record: &log::Record) {
        self.inner.log(record);
        if !self.inner.enabled(record.metadata()) || !record.target().starts_with("ist_monitor") {
            return;
        }
        if let Some((tx, name)) = lock(&self.to).as_ref() {
            let _ = tx.try_send(Log {
                stamp: Time::from_nanos(Time::now_nanos()),
                level: level(record.level()),
                name: name.clone(),
                msg: record.args().to_string(),
                file: record.file().unwrap_or_default().to_owned(),
                function: record.module_path().unwrap_or_default().to_owned(),
                line: record.line().unwrap_or(0),
            });
        }
    }

    fn flush(&self) {
        self.inner.flush();
    }
}

/// Publishing the node's log on `/rosout`; dropping it stops that (the lines queued are sent
/// first).
pub struct Forwarding {
    thread: Option<std::thread::JoinHandle<()>>,
}

/// Starts publishing the node's log lines on `publisher` under the logger name `name` (the
/// node's namespace and name joined with dots: `cell1.ist_monitor`). `None` where the process's
/// logger is not [`RosoutLog`] (a library user's own logger) or the thread cannot start.
pub fn forward(publisher: Pub<Log>, name: String) -> Option<Forwarding> {
    let logger = LOGGER.get()?;
    let (tx, rx) = sync_channel::<Log>(QUEUE);
    let thread = std::thread::Builder::new()
        .name("rosout".into())
        .spawn(move || {
            while let Ok(line) = rx.recv() {
                let _ = publisher.publish(line);
            }
        })
        .ok()?;
    *lock(&logger.to) = Some((tx, name));
    Some(Forwarding {
        thread: Some(thread),
    })
}

impl Drop for Forwarding {
    fn drop(&mut self) {
        if let Some(logger) = LOGGER.get() {
            *lock(&logger.to) = None;
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The logger name of node `name` in namespace `namespace`, as rcl names it.
pub fn logger_name(namespace: &str, name: &str) -> String {
    let ns = namespace.trim_matches('/').replace('/', ".");
    if ns.is_empty() {
        name.to_owned()
    } else {
        format!("{ns}.{name}")
    }
}
