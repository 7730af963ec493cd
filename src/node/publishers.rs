//! The node's publishers: one per row of the output table (`monitor::outputs::OutputTopic`),
//! the node's own counts added to every status (the last word that goes out on them before
//! the node leaves the network is `lifecycle`'s).

use std::any::Any;
use std::time::Duration;

use ros2_client::qos::{Durability, History, QosProfile};

use super::error::{NodeError, Result};
use super::ros_args::remap_topic;
use super::transport::{Pub, RosNode, TopicReaders};
use crate::config::Config;
use crate::monitor::outputs::{visit_output_topics, OutputTopic, OutputVisitor};
use crate::monitor::Outputs;
use crate::msg::OwnedMessage;

/// The node's publishers, one per row of the output table (`OutputTopic`), each a
/// [`Pub<T>`] of that row's message type; and who reads `~/closest_points` by discovery.
pub(super) struct Publishers {
    topics: Vec<(OutputTopic, Box<dyn Any + Send + Sync>)>,
    markers: Option<TopicReaders>,
}

impl Publishers {
    /// A publisher for every output topic of `config`'s node, with `qos`; those published on
    /// every heartbeat offer `output_deadline` as their QoS deadline.
    pub(super) fn new(node: &mut RosNode, config: &Config, qos: QosProfile) -> Result<Self> {
        struct Create<'a> {
            node: &'a mut RosNode,
            node_path: String,
            config: &'a Config,
            qos: QosProfile,
            made: Vec<(OutputTopic, Box<dyn Any + Send + Sync>)>,
            markers: Option<TopicReaders>,
        }
        impl OutputVisitor for Create<'_> {
            type Error = NodeError;
            fn visit<T: OwnedMessage>(&mut self, topic: OutputTopic, _: Option<T>) -> Result<()> {
                let mut qos = if topic.transient_local() {
                    // Reliable, keep the last: what a late-joining controller reads first.
                    self.qos
                        .clone()
                        .durability(Durability::TransientLocal)
                        .history(History::KeepLast { depth: 1 })
                } else {
                    self.qos.clone()
                };
                if topic.every_beat(self.config) {
                    qos = qos.deadline(self.config.output_deadline_s.map(Duration::from_secs_f64));
                }
                let name = remap_topic(
                    &topic.topic(&self.node_path),
                    &self.config.remaps,
                    &self.node_path,
                );
                let p = self.node.publisher::<T>(&name, qos)?;
                self.made.push((topic, Box::new(p)));
                if topic == OutputTopic::ClosestPoints {
                    self.markers = Some(self.node.subscribers::<T>(&name)?);
                }
                Ok(())
            }
        }
        let mut create = Create {
            node,
            node_path: config.node_path(),
            config,
            qos,
            made: Vec::new(),
            markers: None,
        };
        visit_output_topics(&mut create)?;
        Ok(Self {
            topics: create.made,
            markers: create.markers,
        })
    }

    /// Whether anyone reads `~/closest_points` now, by discovery.
    pub(super) fn markers_read(&self) -> Option<bool> {
        self.markers.as_ref().map(TopicReaders::any)
    }

    /// Publishes a frame's outputs; the node's own counts (`dropped` clouds, refused inputs)
    /// join the diagnostics. Where `following`, only the topics that follow a frame's unseen
    /// pass (`Outputs::visit_part`).
    pub(super) fn publish(&self, mut o: Outputs, dropped: u64, input_errors: u64, following: bool) {
        add_counts(&mut o, dropped, input_errors);
        self.publish_topics(o, following);
    }

    pub(super) fn publish_outputs(&self, o: Outputs) {
        self.publish_topics(o, false);
    }

    fn publish_topics(&self, o: Outputs, following: bool) {
        struct Publish<'a>(&'a Publishers);
        impl OutputVisitor for Publish<'_> {
            type Error = String;
            fn visit<T: OwnedMessage>(
                &mut self,
                topic: OutputTopic,
                message: Option<T>,
            ) -> Result<(), String> {
                let Some(m) = message else {
                    return Ok(());
                };
                let publisher = (self.0)
                    .topics
                    .iter()
                    .find(|(t, _)| *t == topic)
                    .and_then(|(_, p)| p.downcast_ref::<Pub<T>>())
                    .ok_or_else(|| format!("{}: no publisher", topic.name()))?;
                publisher
                    .publish(m)
                    .map_err(|e| format!("{}: {e}", topic.name()))
            }
        }
        if let Err(e) = o.visit_part(following, &mut Publish(self)) {
            log::warn!("publishing: {e}");
        }
    }
}

/// The node's own counts (`dropped` clouds, refused inputs), added to every status.
fn add_counts(o: &mut Outputs, dropped: u64, input_errors: u64) {
    for status in &mut o.diagnostics.status {
        status.values.extend([
            crate::msg::KeyValue {
                key: "clouds_dropped".into(),
                value: dropped.to_string(),
            },
            crate::msg::KeyValue {
                key: "input_errors".into(),
                value: input_errors.to_string(),
            },
        ]);
    }
}

/// The environment variable that makes the node panic after that many published frames: a
/// fault injection for the tests of the last word (never set in use).
pub const PANIC_AFTER_ENV: &str = "IST_MONITOR_PANIC_AFTER";
