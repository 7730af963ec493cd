//! The line that says the node is up: its name, the robot and links it watches, the query mode,
//! each enabled source on its topic and the transport; on DDS also the socket receive buffer
//! asked and granted, with a warning when the kernel grants less than a cloud burst needs; and,
//! when SROS2 is asked for, the enclave it runs in or why it runs unsecured.

use super::ros_args::input_topic;
use super::socket::{self, granted_receive_buffer, mib, SOCKET_BUFFER};
use super::transport::{RosNode, Transport};
use crate::config::Config;
use crate::monitor::Monitor;

/// The one line that says the node is up and what it watches, and a warning when the kernel
/// grants less socket buffer than a cloud burst needs.
pub(super) fn log_up(config: &Config, monitor: &Monitor, node: &RosNode) {
    let sources: Vec<String> = config
        .sources
        .iter()
        .filter(|s| s.enabled)
        .map(|s| format!("{} on {}", s.name, input_topic(config, &s.topic)))
        .collect();
    // The socket buffers are DDS's: zenoh's samples travel over TCP.
    let dds = node.transport() == Transport::Dds;
    let granted = dds.then(|| granted_receive_buffer(SOCKET_BUFFER)).flatten();
    let buffer = if dds && socket::forced() {
        format!(
            "; socket receive buffer {} forced (SO_RCVBUFFORCE, CAP_NET_ADMIN)",
            mib(SOCKET_BUFFER)
        )
    } else if dds {
        let short = granted.is_some_and(|g| g < SOCKET_BUFFER);
        format!(
            "; socket receive buffer {} asked, {} granted (net.core.rmem_max{})",
            mib(SOCKET_BUFFER),
            granted.map_or("unknown".into(), mib),
            if short {
                "; no CAP_NET_ADMIN to force it"
            } else {
                ""
            }
        )
    } else {
        String::new()
    };
    log::info!(
        "up: node {} (outputs on ~/ and /diagnostics), robot '{}' ({} links monitored), mode {}, \
         sources: {}; {}{buffer}{security}",
        config.node_path(),
        monitor.model.name,
        monitor.links(),
        format!("{:?}", config.query.mode).to_lowercase(),
        sources.join(", "),
        node.describe,
        security = node
            .security
            .describe()
            .map_or(String::new(), |s| format!("; {s}")),
    );
    if let Some(g) = granted.filter(|&g| g < SOCKET_BUFFER) {
        log::warn!(
            "the kernel grants {} of socket receive buffer (net.core.rmem_max): a cloud larger \
             than that arriving in one burst loses datagrams and is dropped whole; raise it once \
             with `sudo sysctl -w net.core.rmem_max={SOCKET_BUFFER}`, or give the node \
             CAP_NET_ADMIN to force its own (docs/host-setup.md)",
            mib(g)
        );
    }
}
