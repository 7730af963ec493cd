//! A service on zenoh (the folder's **Services**): a queryable answering each CDR request with
//! the CDR response and the attachment by which the client pairs them, announced by its
//! liveliness token.

use std::sync::atomic::Ordering;

use ros2_client::qos::{History, QosProfile};
use zenoh::Wait;

use super::keys::{attachment, mangle, qos_key};
use super::node::ZenohNode;
use crate::node::error::{entity, NodeError};
use crate::node::ros_args::topic_name;

impl ZenohNode {
    /// Answers service `service` (absolute) of type `rcl_interfaces/srv/<ty>` (REP-2016 hash
    /// `hash`) with `answer`, on zenoh's own threads, until the returned server is dropped.
    pub fn service<Req, Resp>(
        &self,
        service: &str,
        ty: &str,
        hash: &str,
        answer: impl Fn(Req) -> Resp + Send + Sync + 'static,
    ) -> Result<ZenohService, NodeError>
    where
        Req: serde::de::DeserializeOwned + 'static,
        Resp: serde::Serialize + 'static,
    {
        topic_name(service)?; // a ROS name, as on DDS
        let service = format!("/{}", service.trim_matches('/'));
        let dds_type = format!("rcl_interfaces::srv::dds_::{ty}_");
        let id = self.next_entity.fetch_add(1, Ordering::Relaxed);
        // rclcpp's services: reliable, volatile, the last 10.
        let qos = QosProfile::publisher_default()
            .reliability_reliable(ros2_client::qos::WhenFull::DEFAULT)
            .history(History::KeepLast { depth: 10 });
        let liveliness = format!(
            "{}/{id}/SS/{}/{}/{dds_type}/{hash}/{}",
            self.lv_prefix,
            self.lv_node,
            mangle(&service),
            qos_key(&qos)
        );
        let name = service.clone();
        let queryable = self
            .session
            .declare_queryable(format!("{}{service}/{dds_type}/*", self.domain))
            .complete(true)
            .callback(move |query| {
                let Some(request) = query.payload().map(|p| p.to_bytes()) else {
                    log::warn!("service {name}: a request without a payload");
                    return;
                };
                let request: Req = match decode_cdr(&request) {
                    Ok(r) => r,
                    Err(e) => {
                        log::warn!("service {name}: a request that does not decode: {e}");
                        return;
                    }
                };
                let mut response = vec![0u8, 1, 0, 0];
                if let Err(e) = cdr_encoding::to_writer::<_, byteorder::LittleEndian, _>(
                    &mut response,
                    &answer(request),
                ) {
                    log::warn!("service {name}: encoding the answer: {e}");
                    return;
                }
                // The client pairs the reply by the request's sequence number and its own gid.
                let (seq, gid) = query.attachment().map_or((0, [0; 16]), |a| {
                    let b = a.to_bytes();
                    let seq = b.get(0..8).and_then(|s| s.try_into().ok());
                    let gid = b.get(16..32).and_then(|g| g.try_into().ok());
                    (seq.map_or(0, i64::from_le_bytes), gid.unwrap_or([0; 16]))
                });
                if let Err(e) = query
                    .reply(query.key_expr().clone(), response)
                    .attachment(attachment(seq, &gid))
                    .wait()
                {
                    log::warn!("service {name}: answering: {e}");
                }
            })
            .wait()
            .map_err(|e| entity("service", &service, e))?;
        let token = self.token(liveliness, "service", &service)?;
        Ok(ZenohService {
            _queryable: queryable,
            _token: token,
        })
    }
}

/// A service answered on zenoh, until dropped.
pub struct ZenohService {
    _queryable: zenoh::query::Queryable<()>,
    _token: zenoh::liveliness::LivelinessToken,
}

/// A CDR payload with its encapsulation header (either byte order) as `T`.
fn decode_cdr<T: serde::de::DeserializeOwned>(payload: &[u8]) -> Result<T, String> {
    let (header, body) = payload
        .split_at_checked(4)
        .ok_or_else(|| format!("{} bytes, no CDR header", payload.len()))?;
    match header[1] {
        1 => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        0 => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        kind => return Err(format!("encapsulation {kind}")),
    }
    .map(|(t, _)| t)
    .map_err(|e| e.to_string())
}
