//! The separation monitor's parameters (`speed_scaling.*`, ISO/TS 15066): the person's speed,
//! the reaction time, the robot's stopping table (m/s → s and m), the uncertainties (m) and
//! how the factor may rise; read into [`SsmParams`].

use super::error::ConfigError;
use super::values::Values;
use crate::separation::{SsmParams, StoppingTable};

/// `speed_scaling.*`, the stopping table checked.
pub(super) fn ssm(v: &Values) -> Result<SsmParams, ConfigError> {
    let d = |name: &str| v.distance(name, name);
    let stopping = StoppingTable {
        speeds_mps: v.numbers(
            "speed_scaling.stopping.speeds",
            "speed_scaling.stopping.speeds",
        )?,
        times_s: v.numbers(
            "speed_scaling.stopping.times",
            "speed_scaling.stopping.times",
        )?,
        distances_m: v.numbers(
            "speed_scaling.stopping.distances",
            "speed_scaling.stopping.distances",
        )?,
    };
    stopping.validate().map_err(|(list, message)| {
        Values::bad(&format!("speed_scaling.stopping.{list}"), message)
    })?;
    let hysteresis = d("speed_scaling.hysteresis")?;
    if hysteresis > 1.0 {
        return Err(Values::bad(
            "speed_scaling.hysteresis",
            format!("{hysteresis} is above 1 (the factor's range)"),
        ));
    }
    Ok(SsmParams {
        enabled: v.bool("speed_scaling.enabled", "speed_scaling.enabled")?,
        human_speed_mps: d("speed_scaling.human_speed")?,
        reaction_time_s: d("speed_scaling.reaction_time")?,
        stopping,
        intrusion_distance_m: d("speed_scaling.intrusion_distance")?,
        sensor_uncertainty_m: d("speed_scaling.sensor_uncertainty")?,
        robot_uncertainty_m: d("speed_scaling.robot_uncertainty")?,
        hysteresis,
        max_increase_rate_per_s: d("speed_scaling.max_increase_rate")?,
        velocities_scaled: v.bool(
            "speed_scaling.velocities_scaled",
            "speed_scaling.velocities_scaled",
        )?,
    })
}
