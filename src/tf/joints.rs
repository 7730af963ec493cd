//! The joint-state buffer: `sensor_msgs/JointState` messages → the joint value vector `q` of
//! the robot's kinematics at a cloud's stamp.
//!
//! Joints are matched by name; names the robot does not have are ignored (a topic may carry
//! several robots, or a gripper published separately). Each joint keeps a short history, so
//! messages that carry only some joints combine. At a stamp, each joint is interpolated linearly
//! between its two samples around the stamp, or takes its nearest sample when that lies within
//! the tolerance. A joint with no sample is missing, one whose newest sample is older than the
//! tolerance is stale: both are errors that name the joint, never a silent zero. Values from the
//! config (`fixed_joint_state`, for bags without `/joint_states`) hold for all time and are
//! overridden by messages.

use crate::msg::JointState;

use super::history::{History, Miss};

/// Samples kept per joint at most (1 s at 1 kHz).
const MAX_SAMPLES: usize = 1024;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JointError {
    #[error("joint {0}: no joint state received")]
    Missing(String),
    #[error(
        "joint {joint}: joint state is stale: newest at {newest_s:.3} s, needed at {stamp_s:.3} s (tolerance {tolerance_s} s)"
    )]
    Stale {
        joint: String,
        newest_s: f64,
        stamp_s: f64,
        tolerance_s: f64,
    },
    #[error("joint {joint}: needed at {stamp_s:.3} s, before the oldest sample kept")]
    TooOld { joint: String, stamp_s: f64 },
    #[error("JointState: {names} names but {positions} positions")]
    Lengths { names: usize, positions: usize },
    #[error("JointState: joint {0} has a position that is not finite")]
    NonFinite(String),
    #[error("joint {0} is not a joint of the robot")]
    NotInRobot(String),
}

#[derive(Debug, Clone)]
pub struct JointStateBuffer {
    variables: Vec<String>,
    /// Per variable, its values over time.
    samples: Vec<History<f64>>,
    fixed: Vec<Option<f64>>,
}

impl JointStateBuffer {
    /// A buffer for the joints `variables` (the kinematics' order).
    pub fn new(variables: &[String]) -> Self {
        Self {
            variables: variables.to_vec(),
            samples: vec![History::default(); variables.len()],
            fixed: vec![None; variables.len()],
        }
    }

    /// Values that hold for all time (from the config); names must be joints of the robot.
    pub fn set_fixed(&mut self, named: &[(String, f64)]) -> Result<(), JointError> {
        for (name, value) in named {
            let i = self
                .variables
                .iter()
                .position(|v| v == name)
                .ok_or_else(|| JointError::NotInRobot(name.clone()))?;
            self.fixed[i] = Some(*value);
        }
        Ok(())
    }

    /// Adds a message. The whole message is refused when its lengths disagree or a position of
    /// a known joint is not finite.
    pub fn insert(&mut self, m: &JointState) -> Result<(), JointError> {
        if m.name.len() != m.position.len() {
            return Err(JointError::Lengths {
                names: m.name.len(),
                positions: m.position.len(),
            });
        }
        let stamp = m.header.stamp.as_nanos();
        let known: Vec<(usize, f64)> = m
            .name
            .iter()
            .zip(&m.position)
            .filter_map(|(n, &p)| self.variables.iter().position(|v| v == n).map(|i| (i, p)))
            .collect();
        if let Some((i, _)) = known.iter().find(|(_, p)| !p.is_finite()) {
            return Err(JointError::NonFinite(self.variables[*i].clone()));
        }
        for (i, p) in known {
            self.samples[i].insert(stamp, p, i64::MAX, MAX_SAMPLES);
        }
        Ok(())
    }

    /// `q` at `stamp_ns` (`None`: the newest values).
    pub fn at(&self, stamp_ns: Option<i64>, tolerance_s: f64) -> Result<Vec<f64>, JointError> {
        let tolerance_ns = (tolerance_s * 1e9) as i64;
        let s = |ns: i64| ns as f64 * 1e-9;
        (0..self.variables.len())
            .map(|i| {
                let joint = || self.variables[i].clone();
                let lerp = |a: &f64, b: &f64, w: f64| a + w * (b - a);
                match self.samples[i].sample(stamp_ns, tolerance_ns, lerp) {
                    None => self.fixed[i].ok_or_else(|| JointError::Missing(joint())),
                    Some(Ok(q)) => Ok(q),
                    Some(Err(Miss::Stale { newest_ns })) => Err(JointError::Stale {
                        joint: joint(),
                        newest_s: s(newest_ns),
                        stamp_s: s(stamp_ns.unwrap_or_default()),
                        tolerance_s,
                    }),
                    Some(Err(Miss::TooOld { .. })) => Err(JointError::TooOld {
                        joint: joint(),
                        stamp_s: s(stamp_ns.unwrap_or_default()),
                    }),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Header, Time};

    fn js(t_ns: i64, names: &[&str], positions: &[f64]) -> JointState {
        JointState {
            header: Header {
                stamp: Time::from_nanos(t_ns),
                frame_id: String::new(),
            },
            name: names.iter().map(|n| n.to_string()).collect(),
            position: positions.to_vec(),
            ..JointState::default()
        }
    }

    #[test]
    fn matches_by_name_interpolates_and_reports_missing_and_stale() {
        let vars = vec!["a".to_string(), "b".to_string()];
        let mut buf = JointStateBuffer::new(&vars);
        // Order in the message differs from the robot's; an unknown joint is ignored.
        buf.insert(&js(0, &["b", "other", "a"], &[2.0, 9.0, 1.0]))
            .unwrap();
        buf.insert(&js(100_000_000, &["a", "b"], &[3.0, 4.0]))
            .unwrap();
        assert_eq!(buf.at(Some(50_000_000), 0.0).unwrap(), vec![2.0, 3.0]);
        assert_eq!(buf.at(None, 0.0).unwrap(), vec![3.0, 4.0]);
        let e = buf.at(Some(400_000_000), 0.1).unwrap_err();
        assert!(matches!(e, JointError::Stale { .. }), "{e}");
        // A joint never published is an error naming it.
        let vars3 = vec!["a".to_string(), "c".to_string()];
        let mut buf = JointStateBuffer::new(&vars3);
        buf.insert(&js(0, &["a"], &[1.0])).unwrap();
        assert_eq!(buf.at(Some(0), 0.1), Err(JointError::Missing("c".into())));
        // ... unless the config fixes it.
        buf.set_fixed(&[("c".into(), 0.5)]).unwrap();
        assert_eq!(buf.at(Some(0), 0.1).unwrap(), vec![1.0, 0.5]);
        assert!(buf.set_fixed(&[("zz".into(), 0.0)]).is_err());
    }

    #[test]
    fn malformed_messages_are_refused() {
        let vars = vec!["a".to_string()];
        let mut buf = JointStateBuffer::new(&vars);
        assert!(matches!(
            buf.insert(&js(0, &["a"], &[])),
            Err(JointError::Lengths { .. })
        ));
        assert!(matches!(
            buf.insert(&js(0, &["a"], &[f64::NAN])),
            Err(JointError::NonFinite(_))
        ));
        assert!(matches!(buf.at(None, 0.1), Err(JointError::Missing(_))));
    }
}
