//! The six `rcl_interfaces` parameter services on the node, DDS or zenoh alike: each request
//! answered from the running [`Parameters`] in a task on the node's executor.

use std::sync::Arc;

use ros2_client::parameters::raw;
use ros2_client::rcl_interfaces as srv;

use super::declared::Parameters;
use crate::node::error::NodeError;
use crate::node::transport::RosNode;

/// The six services of `params` on `node` (DDS and zenoh), each answered in a task on
/// `executor`.
pub fn serve(
    node: &mut RosNode,
    executor: &smol::Executor<'static>,
    params: &Arc<Parameters>,
) -> Result<Vec<smol::Task<()>>, NodeError> {
    let mut tasks = Vec::new();
    let p = params.clone();
    tasks.extend(node.service(
        "list_parameters",
        "ListParameters",
        executor,
        move |r: srv::ListParametersRequest| srv::ListParametersResponse {
            result: p.list(&r.prefixes, r.depth),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "get_parameters",
        "GetParameters",
        executor,
        move |r: srv::GetParametersRequest| srv::GetParametersResponse {
            values: p.get(&r.names),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "get_parameter_types",
        "GetParameterTypes",
        executor,
        move |r: srv::GetParameterTypesRequest| srv::GetParameterTypesResponse {
            values: p.types(&r.names),
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "describe_parameters",
        "DescribeParameters",
        executor,
        move |r: srv::DescribeParametersRequest| srv::DescribeParametersResponse {
            values: p.describe(&r.names),
        },
    )?);
    let result = |r: Result<(), String>| raw::SetParametersResult {
        successful: r.is_ok(),
        reason: r.err().unwrap_or_default(),
    };
    let p = params.clone();
    tasks.extend(node.service(
        "set_parameters",
        "SetParameters",
        executor,
        move |r: srv::SetParametersRequest| {
            srv::SetParametersResponse {
                results: r
                    .parameter
                    .iter()
                    .map(|one| result(p.set(std::slice::from_ref(one))))
                    .collect(),
            }
        },
    )?);
    let p = params.clone();
    tasks.extend(node.service(
        "set_parameters_atomically",
        "SetParametersAtomically",
        executor,
        move |r: srv::SetParametersRequest| srv::SetParametersAtomicallyResponse {
            result: result(p.set(&r.parameter)),
        },
    )?);
    Ok(tasks)
}
