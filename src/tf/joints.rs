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
//!
//! Joint velocities ([`JointStateBuffer::velocities_at`]) come from the messages' `velocity`
//! field where the publisher fills it (interpolated like the positions), and otherwise from the
//! positions, as the slope between the two samples around the stamp; which of the two was used
//! is stated ([`VelocitySource`]). A joint with neither is an error naming it, never a zero.
//! Non-finite velocities (some drivers publish NaN for joints without a sensor) count as not
//! given.
//!
//! **One voice per joint.** Each joint keeps who published it ([`Voices`], by stamp): two
//! writers of one joint within the voice window of the stamp looked up (a second
//! `joint_state_publisher`, a simulator left running beside the driver) is
//! [`JointError::SecondPublisher`] naming the joint and the writers, until one of them has been
//! alone for the window. Joints only one writer publishes may come from several messages. Where
//! the node's discovery gives the topic's writers by GID (DDS: [`JointStateBuffer::set_matched`]),
//! a joint's writer stays its voice for as long as it is matched, however long its messages are
//! lost: a second writer of that joint is then the conflict too.

use crate::msg::{JointState, Voices, Writer};

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
    #[error("JointState: {names} names but {velocities} velocities (empty or one per name)")]
    VelocityLengths { names: usize, velocities: usize },
    #[error("joint {joint}: published by more than one writer: {writers}")]
    SecondPublisher { joint: String, writers: String },
    #[error(
        "joint {0}: no velocity: the joint states carry none, and there are not two positions \
         within joint_state_tolerance to differentiate"
    )]
    NoVelocity(String),
}

/// Where the joint velocities of a stamp came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocitySource {
    /// Every joint's from the messages' `velocity` field (or held by `fixed_joint_state`).
    JointStates,
    /// Every joint's differentiated from its positions.
    Differentiated,
    /// Some of each.
    Mixed,
}

impl VelocitySource {
    pub fn name(self) -> &'static str {
        match self {
            VelocitySource::JointStates => "joint_states",
            VelocitySource::Differentiated => "differentiated",
            VelocitySource::Mixed => "mixed",
        }
    }
}

#[derive(Debug, Clone)]
pub struct JointStateBuffer {
    variables: Vec<String>,
    /// Per variable, its values over time.
    samples: Vec<History<f64>>,
    /// Per variable, the velocities the messages gave.
    velocities: Vec<History<f64>>,
    fixed: Vec<Option<f64>>,
    /// Per variable, who published it.
    voices: Vec<Voices>,
    /// Two writers of one joint within this of a stamp are a conflict.
    voice_window_ns: i64,
    /// The writers discovery matches on the topic now (empty: none known).
    matched: Vec<Writer>,
}

impl JointStateBuffer {
    /// A buffer for the joints `variables` (the kinematics' order).
    pub fn new(variables: &[String]) -> Self {
        Self {
            variables: variables.to_vec(),
            samples: vec![History::default(); variables.len()],
            velocities: vec![History::default(); variables.len()],
            fixed: vec![None; variables.len()],
            voices: vec![Voices::default(); variables.len()],
            voice_window_ns: (crate::tf::VOICE_WINDOW_S * 1e9) as i64,
            matched: Vec::new(),
        }
    }

    /// The writers that discovery matches on the joint states' topic now (empty: no
    /// discovery): a joint's writer stays its voice while it is matched, however long its
    /// messages are lost.
    pub fn set_matched(&mut self, writers: Vec<Writer>) {
        self.matched = writers;
    }

    /// Two writers of one joint within `window_s` of a stamp are a conflict.
    pub fn set_voice_window(&mut self, window_s: f64) {
        self.voice_window_ns = (window_s * 1e9) as i64;
    }

    /// Joint `i`'s writers at `stamp_ns` (`None`: its newest sample's), an error when two
    /// are heard.
    fn one_voice(&self, i: usize, stamp_ns: Option<i64>) -> Result<(), JointError> {
        let Some(at) = stamp_ns.or_else(|| self.samples[i].newest_stamp()) else {
            return Ok(());
        };
        match self.voices[i].conflict(at, self.voice_window_ns, &self.matched) {
            None => Ok(()),
            Some(writers) => Err(JointError::SecondPublisher {
                joint: self.variables[i].clone(),
                writers: Writer::list(&writers),
            }),
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

    /// Forgets the joint states received (the fixed values are kept).
    pub fn forget(&mut self) {
        self.samples.iter_mut().for_each(History::clear);
        self.velocities.iter_mut().for_each(History::clear);
        self.voices.iter_mut().for_each(Voices::forget);
    }

    /// Adds a message of no known writer (a bag's). The whole message is refused when its
    /// lengths disagree or a position of a known joint is not finite.
    pub fn insert(&mut self, m: &JointState) -> Result<(), JointError> {
        self.insert_from(m, Writer::UNKNOWN)
    }

    /// Adds a message published by `writer` (as [`JointStateBuffer::insert`]).
    pub fn insert_from(&mut self, m: &JointState, writer: Writer) -> Result<(), JointError> {
        if m.name.len() != m.position.len() {
            return Err(JointError::Lengths {
                names: m.name.len(),
                positions: m.position.len(),
            });
        }
        if !m.velocity.is_empty() && m.velocity.len() != m.name.len() {
            return Err(JointError::VelocityLengths {
                names: m.name.len(),
                velocities: m.velocity.len(),
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
            self.voices[i].hear(writer, stamp);
        }
        for (n, &v) in m.name.iter().zip(&m.velocity) {
            if let Some(i) = self.variables.iter().position(|x| x == n) {
                if v.is_finite() {
                    self.velocities[i].insert(stamp, v, i64::MAX, MAX_SAMPLES);
                }
            }
        }
        Ok(())
    }

    /// `q̇` at `stamp_ns` (`None`: the newest), and where it came from: per joint, the given
    /// velocity within the tolerance, else the slope of its positions (two samples at most
    /// `tolerance_s` apart), else 0 for a joint held by `fixed_joint_state` with no message.
    pub fn velocities_at(
        &self,
        stamp_ns: Option<i64>,
        tolerance_s: f64,
    ) -> Result<(Vec<f64>, VelocitySource), JointError> {
        let tolerance_ns = (tolerance_s * 1e9) as i64;
        let lerp = |a: &f64, b: &f64, w: f64| a + w * (b - a);
        let (mut given, mut derived) = (0, 0);
        let mut q_dot = Vec::with_capacity(self.variables.len());
        for i in 0..self.variables.len() {
            self.one_voice(i, stamp_ns)?;
            let v = if let Some(Ok(v)) = self.velocities[i].sample(stamp_ns, tolerance_ns, lerp) {
                given += 1;
                v
            } else if let Some(Ok(v)) = self.samples[i].slope(stamp_ns, tolerance_ns, tolerance_ns)
            {
                derived += 1;
                v
            } else if self.fixed[i].is_some() && self.samples[i].sample(None, 0, lerp).is_none() {
                given += 1;
                0.0
            } else {
                return Err(JointError::NoVelocity(self.variables[i].clone()));
            };
            q_dot.push(v);
        }
        let source = match (given, derived) {
            (_, 0) => VelocitySource::JointStates,
            (0, _) => VelocitySource::Differentiated,
            _ => VelocitySource::Mixed,
        };
        Ok((q_dot, source))
    }

    /// `q` at `stamp_ns` (`None`: the newest values).
    pub fn at(&self, stamp_ns: Option<i64>, tolerance_s: f64) -> Result<Vec<f64>, JointError> {
        let tolerance_ns = (tolerance_s * 1e9) as i64;
        let s = |ns: i64| ns as f64 * 1e-9;
        (0..self.variables.len())
            .map(|i| {
                let joint = || self.variables[i].clone();
                self.one_voice(i, stamp_ns)?;
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
    fn velocities_given_or_differentiated_and_said_which() {
        let vars = vec!["a".to_string(), "b".to_string()];
        let mut buf = JointStateBuffer::new(&vars);
        let mut m = js(0, &["a", "b"], &[0.0, 1.0]);
        m.velocity = vec![0.5, f64::NAN];
        buf.insert(&m).unwrap();
        // One sample: b's velocity is NaN (not given) and cannot be differentiated yet.
        assert_eq!(
            buf.velocities_at(Some(0), 0.1),
            Err(JointError::NoVelocity("b".into()))
        );
        let mut m = js(50_000_000, &["a", "b"], &[0.1, 0.9]);
        m.velocity = vec![1.5, f64::NAN];
        buf.insert(&m).unwrap();
        let (q_dot, source) = buf.velocities_at(Some(25_000_000), 0.1).unwrap();
        assert!((q_dot[0] - 1.0).abs() < 1e-12, "given, interpolated");
        assert!(
            (q_dot[1] + 2.0).abs() < 1e-9,
            "b differentiated: -0.1 in 0.05 s"
        );
        assert_eq!(source, VelocitySource::Mixed);
        // Positions only: differentiated.
        let mut buf = JointStateBuffer::new(&vars);
        buf.insert(&js(0, &["a", "b"], &[0.0, 0.0])).unwrap();
        buf.insert(&js(20_000_000, &["a", "b"], &[0.02, -0.04]))
            .unwrap();
        let (q_dot, source) = buf.velocities_at(Some(30_000_000), 0.1).unwrap();
        assert!((q_dot[0] - 1.0).abs() < 1e-9 && (q_dot[1] + 2.0).abs() < 1e-9);
        assert_eq!(source, VelocitySource::Differentiated);
        // A stale stamp has no velocity either.
        assert!(buf.velocities_at(Some(900_000_000), 0.1).is_err());
        // A velocity array of the wrong length refuses the message.
        let mut m = js(40_000_000, &["a", "b"], &[0.0, 0.0]);
        m.velocity = vec![1.0];
        assert!(matches!(
            buf.insert(&m),
            Err(JointError::VelocityLengths { .. })
        ));
        // A joint held by the config moves at 0.
        let mut buf = JointStateBuffer::new(&vars);
        buf.set_fixed(&[("b".into(), 0.3)]).unwrap();
        let mut m = js(0, &["a"], &[0.0]);
        m.velocity = vec![0.7];
        buf.insert(&m).unwrap();
        assert_eq!(
            buf.velocities_at(Some(0), 0.1).unwrap(),
            (vec![0.7, 0.0], VelocitySource::JointStates)
        );
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

    #[test]
    fn a_joint_from_two_writers_is_an_error_until_one_is_alone_for_the_window() {
        let vars = vec!["a".to_string(), "b".to_string()];
        let mut buf = JointStateBuffer::new(&vars);
        buf.set_voice_window(0.5);
        let (w1, w2) = (Writer([1; 16]), Writer([2; 16]));
        // Two writers of different joints combine.
        buf.insert_from(&js(0, &["a"], &[1.0]), w1).unwrap();
        buf.insert_from(&js(0, &["b"], &[2.0]), w2).unwrap();
        assert_eq!(buf.at(Some(0), 0.1).unwrap(), vec![1.0, 2.0]);
        // A second writer of joint a.
        buf.insert_from(&js(10_000_000, &["a", "b"], &[0.0, 2.0]), w1)
            .unwrap();
        buf.insert_from(&js(20_000_000, &["a"], &[1.5]), w2)
            .unwrap();
        let e = buf.at(Some(20_000_000), 0.1).unwrap_err();
        assert!(
            matches!(&e, JointError::SecondPublisher { joint, .. } if joint == "a"),
            "{e}"
        );
        assert!(buf.velocities_at(Some(20_000_000), 0.1).is_err());
        assert!(buf.at(None, 0.1).is_err());
        // w2 falls silent; w1 alone for the window: its values are taken again.
        buf.insert_from(&js(600_000_000, &["a", "b"], &[0.3, 2.0]), w1)
            .unwrap();
        assert_eq!(buf.at(Some(600_000_000), 0.1).unwrap(), vec![0.3, 2.0]);
        buf.insert_from(&js(610_000_000, &["a"], &[0.4]), w2)
            .unwrap();
        buf.forget();
        buf.insert_from(&js(700_000_000, &["a", "b"], &[0.5, 2.0]), w1)
            .unwrap();
        assert_eq!(buf.at(None, 0.1).unwrap(), vec![0.5, 2.0]);
    }
}
