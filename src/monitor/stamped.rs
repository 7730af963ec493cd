//! `~/distance` and `~/unseen_distance` as `sensor_msgs/Range`: a distance stamped with the
//! time it holds for, in the robot's root frame (NaN: none known, REP 117).

use crate::config::Config;
use crate::msg::{Header, Range};

/// `~/distance`: the conservative distance `d` stamped with `header` (NaN: none known).
pub fn stamped_distance(config: &Config, header: &Header, d: Option<f64>) -> Range {
    Range {
        header: header.clone(),
        // Depth cameras and lidars are infrared sensors; the field has no better value.
        radiation_type: 1,
        field_of_view: 0.0,
        min_range: 0.0,
        max_range: config.query.max_distance_m,
        range: d.map_or(f32::NAN, |d| d as f32),
        variance: 0.0,
    }
}
