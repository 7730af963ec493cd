//! The node's parameters on the graph, as `ros2 param` and rclpy reach them: the six
//! `rcl_interfaces` services (`~/list_parameters`, `~/get_parameters`,
//! `~/get_parameter_types`, `~/describe_parameters`, `~/set_parameters`,
//! `~/set_parameters_atomically`) and `/parameter_events`.
//!
//! Every parameter comes from the one declaration (`config::PARAMETERS`), expanded per list
//! entry (`Config::parameters`): its value, its type (read from the declared default; one
//! without a default takes the type of its value), its meaning as the description, its unit as
//! the additional constraint, `[0, ∞]` as the range of a quantity, and read-only unless it is
//! declared settable at run time.
//!
//! A set is a change of the running config (`Config::with_changes`): checked as at start (an
//! attached object also against the robot's links), refused with the reason (the parameter
//! named) or taken whole. `set_parameters` takes its
//! parameters one after the other, each its own change with its own result, as rclcpp does;
//! `set_parameters_atomically` takes them as one change (the way to add an exclusion volume
//! with its parameters). While the safety stop is raised a change that could release it is
//! refused (`Config::weakening`, from the processing thread's latest [`Safety`]). A change
//! taken is sent to the processing thread, which applies it before its next frame
//! (`Monitor::reconfigure`), and published on `/parameter_events` (new, changed and deleted
//! parameters, as rclcpp reports them).
//!
//! The services run on DDS and on zenoh (as rmw_zenoh offers services: `rmw_zenoh`), and so
//! does `/parameter_events` (`rcl_interfaces/msg/ParameterEvent`, stamped by the node's clock:
//! simulated time with `use_sim_time`, as rclcpp stamps it).
//!
//! Here: `declared`, the running set ([`Parameters`]: list, get, describe, set) and the safety
//! a change is checked against; `values`, a parameter between the config's YAML and ROS 2's
//! typed values, its descriptor and the event of a change; `services`, the six services on
//! the node.

mod declared;
mod services;
mod values;

pub use declared::{Parameters, RobotLinks, Safety};
pub use services::serve;
