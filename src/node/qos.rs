//! The QoS every topic of the node is made with: its inputs as their publishers offer them
//! (sensor data best effort, `/tf_static` and `/robot_description` transient local, `/clock`
//! as rclcpp's time source takes it), its outputs reliable with a liveliness lease, its log as
//! rcl's, and a source's DDS topic bounded to the samples it needs.

use std::time::Duration;

use ros2_client::qos::{Durability, History, QosProfile, WhenFull};

/// QoS of sensor data: best effort, newest only.
pub const SENSOR_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_best_effort()
    .history(History::KeepLast { depth: 1 });
/// QoS of `/tf_static`: reliable, transient local (late joiners get the transforms).
pub const TF_STATIC_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 100 });
/// QoS of `/robot_description`, as robot_state_publisher offers it: reliable, transient local,
/// the last one.
pub const ROBOT_DESCRIPTION_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1 });
/// QoS of `/clock`, as rclcpp's TimeSource subscribes (`ClockQoS`: best effort, the last one):
/// a reliable publisher (rosbag2, Gazebo) is matched too.
pub const CLOCK_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_best_effort()
    .history(History::KeepLast { depth: 1 });
/// QoS of `/rosout`, as rcl publishes a node's log: reliable, transient local, the last 1000
/// kept for 10 s.
pub const ROSOUT_QOS: QosProfile = QosProfile::publisher_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .durability(Durability::TransientLocal)
    .history(History::KeepLast { depth: 1000 })
    .lifespan(Some(Duration::from_secs(10)));
/// QoS of `/tf` and outputs: reliable, a short history.
pub const RELIABLE_QOS: QosProfile = QosProfile::subscription_default()
    .reliability_reliable(WhenFull::DEFAULT)
    .history(History::KeepLast { depth: 10 });

/// The automatic-liveliness lease every output offers: the participant asserts it, so a
/// subscriber that asks for this lease or a longer one learns that the node is gone. RustDDS
/// asserts automatic liveliness on a 1 s tick once half the shortest lease has passed, so a
/// lease under about 3 s could lapse while the node runs.
pub const OUTPUT_LIVELINESS_LEASE: Duration = Duration::from_secs(3);

/// QoS of the node's outputs: reliable, a short history, a writer blocked by a full reader
/// waits 5 ms at most, and the automatic liveliness of [`OUTPUT_LIVELINESS_LEASE`].
pub const OUTPUT_QOS: QosProfile = QosProfile::publisher_default()
    .reliability_reliable(WhenFull::Wait(Duration::from_millis(5)))
    .history(History::KeepLast { depth: 10 })
    .liveliness_lease(Some(OUTPUT_LIVELINESS_LEASE));

/// Samples a source's DDS topic cache may hold: the newest, and the one being handed over.
/// RustDDS keeps 64 samples of a topic whose QoS sets no resource limits, whatever the reader's
/// history depth: 627 MB of 9.8 MB clouds.
pub const SOURCE_SAMPLES: i32 = 2;

/// The DDS QoS of a source's topic: `qos` with at most [`SOURCE_SAMPLES`] samples kept.
pub fn source_topic_qos(qos: &QosProfile) -> ros2_client::dds::rustdds::QosPolicies {
    use ros2_client::dds::rustdds::{policy::ResourceLimits, QosPolicies, QosPolicyBuilder};
    let limits = QosPolicyBuilder::new()
        .resource_limits(ResourceLimits {
            max_samples: SOURCE_SAMPLES,
            max_instances: 1,
            max_samples_per_instance: SOURCE_SAMPLES,
        })
        .build();
    QosPolicies::from(qos).modify_by(&limits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn source_topics_keep_two_samples() {
        use ros2_client::dds::rustdds::policy;
        for qos in [
            SENSOR_QOS,
            RELIABLE_QOS.history(History::KeepLast { depth: 1 }),
        ] {
            let q = source_topic_qos(&qos);
            let limits = q.resource_limits().expect("resource limits set");
            assert_eq!(limits.max_samples, SOURCE_SAMPLES);
            assert_eq!(limits.max_samples_per_instance, SOURCE_SAMPLES);
            // The rest of the profile is kept.
            assert_eq!(q.history(), Some(policy::History::KeepLast { depth: 1 }));
            assert_eq!(
                matches!(q.reliability(), Some(policy::Reliability::BestEffort)),
                qos == SENSOR_QOS
            );
        }
    }
}
