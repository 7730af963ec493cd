//! Forward kinematics in f64: joint values → `root_from_link` for every link of the URDF tree.
//!
//! The tree is checked once when built (one root, one parent joint per link, no cycle, every
//! joint naming existing links) and its joints are stored in an order where a joint's parent
//! link is always posed before it, so a pose update is one pass over the joints: for joint j,
//! `root_from_child = root_from_parent · origin_j · motion_j(q)`. Revolute and continuous joints
//! rotate about their axis, prismatic ones translate along it, fixed ones do not move. Floating,
//! planar and spherical joints are held at their origin (a warning says so). A mimic joint
//! follows `multiplier · q_master + offset`.
//!
//! Velocities ([`Kinematics::link_velocities`]) go through the same pass: a link's motion is a
//! twist — its angular velocity ω and the velocity `v₀` of the body point at the root's origin,
//! so that a point `p` of the link moves at `v₀ + ω × p` (root frame). A revolute joint with
//! unit axis `a` through `o` (both in the root frame) adds `q̇·a` to ω and `q̇·(o × a)` to `v₀`;
//! a prismatic one adds `q̇·a` to `v₀`. Summed from the root outwards this is the link's
//! geometric Jacobian times q̇, without forming the Jacobian.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

use super::error::RobotError;

/// How a joint moves its child link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointMotion {
    Fixed,
    Revolute(Unit<Vector3<f64>>),
    Prismatic(Unit<Vector3<f64>>),
}

/// Where a joint's value comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum JointSource {
    /// No value: fixed joints and held joints.
    None,
    /// The `i`-th entry of the joint value vector.
    Variable(usize),
    /// `multiplier · q[variable] + offset`.
    Mimic {
        variable: usize,
        multiplier: f64,
        offset: f64,
    },
}

#[derive(Debug, Clone)]
pub struct Joint {
    pub name: String,
    pub parent: usize,
    pub child: usize,
    pub parent_from_joint: Isometry3<f64>,
    pub motion: JointMotion,
    pub source: JointSource,
    /// A prismatic joint's largest travel from its origin, m (its URDF limits; `None` where
    /// they are not given); 0 for other joints.
    pub travel_m: Option<f64>,
}

/// The kinematic tree of a robot.
#[derive(Debug, Clone)]
pub struct Kinematics {
    link_names: Vec<String>,
    root: usize,
    /// Joints in an order where each parent link is posed before the child.
    joints: Vec<Joint>,
    /// Names of the joints whose values drive the robot (the entries of `q`).
    variables: Vec<String>,
}

/// `parent_from_joint` of a URDF origin (fixed-axis roll, pitch, yaw).
pub fn pose_from_urdf(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = *pose.xyz;
    let [roll, pitch, yaw] = *pose.rpy;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

impl Kinematics {
    /// Builds and checks the tree. `path` names the URDF in errors.
    pub fn from_urdf(robot: &urdf_rs::Robot, path: &str) -> Result<Self, RobotError> {
        let link_names: Vec<String> = robot.links.iter().map(|l| l.name.clone()).collect();
        let links = joint_links(robot, &link_names, path)?;
        let root = root_link(&links, &link_names, path)?;
        let order = joint_order(robot, &links, root, path)?;
        let JointMotions {
            motions,
            variables,
            variable_of,
        } = joint_motions(robot, path)?;
        let mut joints = Vec::with_capacity(links.joints.len());
        for &j in &order {
            let joint = &robot.joints[j];
            let (parent, child) = links.joints[j];
            joints.push(Joint {
                name: joint.name.clone(),
                parent,
                child,
                parent_from_joint: pose_from_urdf(&joint.origin),
                motion: motions[j],
                source: joint_source(joint, motions[j], &variable_of, path)?,
                travel_m: travel(joint, motions[j]),
            });
        }
        Ok(Self {
            link_names,
            root,
            joints,
            variables,
        })
    }

    /// Adds link `child` under `parent` by a fixed joint `joint` at `parent_from_child`.
    pub fn add_fixed_link(
        &mut self,
        joint: &str,
        child: &str,
        parent: usize,
        parent_from_child: Isometry3<f64>,
    ) {
        let child_index = self.link_names.len();
        self.link_names.push(child.to_owned());
        // The parent is posed already (it is in the tree), so the joint goes last.
        self.joints.push(Joint {
            name: joint.to_owned(),
            parent,
            child: child_index,
            parent_from_joint: parent_from_child,
            motion: JointMotion::Fixed,
            source: JointSource::None,
            travel_m: Some(0.0),
        });
    }

    pub fn link_names(&self) -> &[String] {
        &self.link_names
    }
    pub fn root_link(&self) -> &str {
        &self.link_names[self.root]
    }
    pub fn link_index(&self, name: &str) -> Option<usize> {
        self.link_names.iter().position(|n| n == name)
    }
    /// The joints whose values form `q`, in order.
    pub fn variables(&self) -> &[String] {
        &self.variables
    }

    /// Joint values from `name = value` pairs. Unknown names are an error; joints not named are
    /// an error unless `default` is given.
    pub fn values_from_names(
        &self,
        named: &[(String, f64)],
        default: Option<f64>,
    ) -> Result<Vec<f64>, RobotError> {
        let mut q: Vec<Option<f64>> = vec![None; self.variables.len()];
        for (name, value) in named {
            let i = self
                .variables
                .iter()
                .position(|v| v == name)
                .ok_or_else(|| RobotError::UnknownJoint(name.clone()))?;
            q[i] = Some(*value);
        }
        q.iter()
            .zip(&self.variables)
            .map(|(v, name)| {
                v.or(default)
                    .ok_or_else(|| RobotError::MissingJoint(name.clone()))
            })
            .collect()
    }

    /// The robot's reach from its root's origin over the links with a body (`radii[l] > 0`):
    /// no point of link `l` within `radii[l]` of the link's origin (indexed like [`Self::link_names`], m) ever lies farther, whatever the
    /// joint values, since a revolute joint turns about its own origin and a fixed one does not
    /// move: along each chain the joints' offsets add up, and a prismatic joint's travel. `None`
    /// with a prismatic joint whose URDF gives no limits.
    pub fn reach_m(&self, radii: &[f64]) -> Option<f64> {
        let mut chain = vec![0.0; self.link_names.len()];
        for joint in &self.joints {
            let offset = joint.parent_from_joint.translation.vector.norm();
            chain[joint.child] = chain[joint.parent] + offset + joint.travel_m?;
        }
        // Only links with a body (radius > 0) reach anywhere: a camera's link does not.
        Some(
            (chain.iter().zip(radii))
                .filter(|(_, &r)| r > 0.0)
                .map(|(c, r)| c + r)
                .fold(0.0, f64::max),
        )
    }

    /// `root_from_link` for every link, indexed like [`Self::link_names`].
    pub fn link_poses(&self, q: &[f64]) -> Vec<Isometry3<f64>> {
        let mut poses = vec![Isometry3::identity(); self.link_names.len()];
        for joint in &self.joints {
            let value = joint.source.value(q);
            let motion = match joint.motion {
                JointMotion::Fixed => Isometry3::identity(),
                JointMotion::Revolute(axis) => Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&axis, value),
                ),
                JointMotion::Prismatic(axis) => Isometry3::from_parts(
                    Translation3::from(axis.into_inner() * value),
                    UnitQuaternion::identity(),
                ),
            };
            poses[joint.child] = poses[joint.parent] * joint.parent_from_joint * motion;
        }
        poses
    }

    /// The twist of every link, indexed like [`Self::link_names`], for joint values `q`, joint
    /// velocities `q_dot` (same order, rad/s or m/s) and the link poses `poses` of `q`.
    pub fn link_velocities(&self, q_dot: &[f64], poses: &[Isometry3<f64>]) -> Vec<LinkVelocity> {
        let mut twists = vec![LinkVelocity::default(); self.link_names.len()];
        for joint in &self.joints {
            let rate = joint.source.rate(q_dot);
            let root_from_joint = poses[joint.parent] * joint.parent_from_joint;
            let mut t = twists[joint.parent];
            match joint.motion {
                JointMotion::Fixed => {}
                JointMotion::Revolute(axis) => {
                    let a = root_from_joint.rotation * axis.into_inner();
                    let o = root_from_joint.translation.vector;
                    t.angular += rate * a;
                    t.linear += rate * o.cross(&a);
                }
                JointMotion::Prismatic(axis) => {
                    t.linear += rate * (root_from_joint.rotation * axis.into_inner());
                }
            }
            twists[joint.child] = t;
        }
        twists
    }
}

/// The motion of a link in the root frame: its angular velocity and the velocity of the body
/// point at the root's origin.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LinkVelocity {
    /// rad/s.
    pub angular: Vector3<f64>,
    /// m/s.
    pub linear: Vector3<f64>,
}

impl LinkVelocity {
    /// The velocity of the link's point at `p` (root frame), m/s.
    pub fn at(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.linear + self.angular.cross(p)
    }
}

impl JointSource {
    /// The joint's value from the variables `q` (0 for a joint without one).
    fn value(&self, q: &[f64]) -> f64 {
        match *self {
            JointSource::None => 0.0,
            JointSource::Variable(i) => q[i],
            JointSource::Mimic {
                variable,
                multiplier,
                offset,
            } => multiplier * q[variable] + offset,
        }
    }

    /// The joint's rate from the variables' rates `q_dot` (a mimic joint's offset is constant).
    fn rate(&self, q_dot: &[f64]) -> f64 {
        match *self {
            JointSource::None => 0.0,
            JointSource::Variable(i) => q_dot[i],
            JointSource::Mimic {
                variable,
                multiplier,
                ..
            } => multiplier * q_dot[variable],
        }
    }
}

/// An error in the shape of the URDF's tree.
fn topology(path: &str, message: String) -> RobotError {
    RobotError::Topology {
        path: path.to_owned(),
        message,
    }
}

/// Each joint's links, by index, and each link's parent joint.
struct JointLinks {
    /// (parent, child) of every joint, in URDF order.
    joints: Vec<(usize, usize)>,
    parent_joint: Vec<Option<usize>>,
}

/// The links every joint names, checked: link names unique and present, one parent joint per
/// link, origins and axes finite.
fn joint_links(
    robot: &urdf_rs::Robot,
    link_names: &[String],
    path: &str,
) -> Result<JointLinks, RobotError> {
    let link_index: HashMap<&str, usize> = link_names
        .iter()
        .enumerate()
        .map(|(i, n)| (n.as_str(), i))
        .collect();
    if link_index.len() != link_names.len() {
        return Err(topology(path, "two links share a name".into()));
    }
    if link_names.is_empty() {
        return Err(topology(path, "the robot has no links".into()));
    }
    let find = |joint: &str, link: &str| {
        link_index.get(link).copied().ok_or_else(|| {
            topology(
                path,
                format!("joint {joint} names link {link}, which does not exist"),
            )
        })
    };
    let mut parent_joint: Vec<Option<usize>> = vec![None; link_names.len()];
    let mut raw = Vec::with_capacity(robot.joints.len());
    for (j, joint) in robot.joints.iter().enumerate() {
        let parent = find(&joint.name, &joint.parent.link)?;
        let child = find(&joint.name, &joint.child.link)?;
        if let Some(other) = parent_joint[child] {
            return Err(topology(
                path,
                format!(
                    "link {} has two parent joints, {} and {}",
                    joint.child.link, robot.joints[other].name, joint.name
                ),
            ));
        }
        parent_joint[child] = Some(j);
        let values = joint.origin.xyz.iter().chain(joint.origin.rpy.iter());
        let axis = *joint.axis.xyz;
        if values.chain(axis.iter()).any(|v| !v.is_finite()) {
            return Err(RobotError::NonFinite {
                path: path.to_owned(),
                element: format!("joint {} origin or axis", joint.name),
            });
        }
        raw.push((parent, child));
    }
    Ok(JointLinks {
        joints: raw,
        parent_joint,
    })
}

/// The one link without a parent joint.
fn root_link(links: &JointLinks, link_names: &[String], path: &str) -> Result<usize, RobotError> {
    let roots: Vec<usize> = (0..link_names.len())
        .filter(|&l| links.parent_joint[l].is_none())
        .collect();
    match roots.as_slice() {
        [root] => Ok(*root),
        [] => Err(topology(
            path,
            "no root link: the joints form a cycle".into(),
        )),
        many => Err(topology(
            path,
            format!(
                "{} root links ({}); a URDF is one tree",
                many.len(),
                many.iter()
                    .map(|&l| link_names[l].as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        )),
    }
}

/// The joints breadth-first from the root, so that a joint's parent link is posed before it;
/// joints never reached lie on a cycle.
fn joint_order(
    robot: &urdf_rs::Robot,
    links: &JointLinks,
    root: usize,
    path: &str,
) -> Result<Vec<usize>, RobotError> {
    let raw = &links.joints;
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.parent_joint.len()];
    for (j, &(parent, _)) in raw.iter().enumerate() {
        children[parent].push(j);
    }
    let mut order = Vec::with_capacity(raw.len());
    let mut frontier = vec![root];
    while let Some(link) = frontier.pop() {
        for &j in &children[link] {
            order.push(j);
            frontier.push(raw[j].1);
        }
    }
    if order.len() != raw.len() {
        let reached: std::collections::HashSet<usize> = order.iter().copied().collect();
        let cycle: Vec<&str> = (0..raw.len())
            .filter(|j| !reached.contains(j))
            .map(|j| robot.joints[j].name.as_str())
            .collect();
        return Err(topology(
            path,
            format!(
                "joints {} form a cycle detached from the root",
                cycle.join(", ")
            ),
        ));
    }
    Ok(order)
}

/// How the joints move, and which of them drive the robot.
struct JointMotions<'r> {
    /// Per joint, in URDF order.
    motions: Vec<JointMotion>,
    /// The joints whose values are the entries of `q`, in order.
    variables: Vec<String>,
    /// Each of those joints' entry.
    variable_of: HashMap<&'r str, usize>,
}

/// A prismatic joint's largest travel (its limits; `None` where both are 0, as urdf-rs reads a
/// joint without `<limit>`); 0 for other joints.
fn travel(joint: &urdf_rs::Joint, motion: JointMotion) -> Option<f64> {
    match motion {
        JointMotion::Prismatic(_) => {
            let (lo, hi) = (joint.limit.lower, joint.limit.upper);
            let t = lo.abs().max(hi.abs());
            (t > 0.0 && t.is_finite()).then_some(t)
        }
        _ => Some(0.0),
    }
}

/// How each joint moves; a joint that moves and mimics none drives the robot.
fn joint_motions<'r>(
    robot: &'r urdf_rs::Robot,
    path: &str,
) -> Result<JointMotions<'r>, RobotError> {
    let mut variables = Vec::new();
    let mut variable_of: HashMap<&str, usize> = HashMap::new();
    let mut motions = Vec::with_capacity(robot.joints.len());
    for joint in &robot.joints {
        let axis = Vector3::from(*joint.axis.xyz);
        let unit = || {
            Unit::try_new(axis, 1e-12).ok_or_else(|| RobotError::NonFinite {
                path: path.to_owned(),
                element: format!("joint {} axis is zero", joint.name),
            })
        };
        use urdf_rs::JointType as T;
        let motion = match joint.joint_type {
            T::Revolute | T::Continuous => JointMotion::Revolute(unit()?),
            T::Prismatic => JointMotion::Prismatic(unit()?),
            T::Fixed => JointMotion::Fixed,
            T::Floating | T::Planar | T::Spherical => {
                log::warn!(
                    "{path}: joint {} is {:?}; it is held at its origin",
                    joint.name,
                    joint.joint_type
                );
                JointMotion::Fixed
            }
        };
        if motion != JointMotion::Fixed && joint.mimic.is_none() {
            variable_of.insert(joint.name.as_str(), variables.len());
            variables.push(joint.name.clone());
        }
        motions.push(motion);
    }
    Ok(JointMotions {
        motions,
        variables,
        variable_of,
    })
}

/// Where a joint's value comes from: none for a fixed joint, its own entry of `q`, or the
/// entry of the joint it mimics.
fn joint_source(
    joint: &urdf_rs::Joint,
    motion: JointMotion,
    variable_of: &HashMap<&str, usize>,
    path: &str,
) -> Result<JointSource, RobotError> {
    Ok(match (&joint.mimic, motion) {
        (_, JointMotion::Fixed) => JointSource::None,
        (None, _) => JointSource::Variable(variable_of[joint.name.as_str()]),
        (Some(mimic), _) => {
            let variable = *variable_of.get(mimic.joint.as_str()).ok_or_else(|| {
                topology(
                    path,
                    format!(
                        "joint {} mimics {}, which is not a moving, non-mimic joint",
                        joint.name, mimic.joint
                    ),
                )
            })?;
            JointSource::Mimic {
                variable,
                multiplier: mimic.multiplier.unwrap_or(1.0),
                offset: mimic.offset.unwrap_or(0.0),
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain(extra: &str) -> Result<Kinematics, RobotError> {
        let xml = format!(
            r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
            <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
              <origin xyz="1 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
            <joint name="j2" type="prismatic"><parent link="b"/><child link="c"/>
              <origin xyz="0 0 0"/><axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/>
              <mimic joint="j1" multiplier="2" offset="0.5"/></joint>{extra}</robot>"#
        );
        let robot = urdf_rs::read_from_string(&xml).expect("xml");
        Kinematics::from_urdf(&robot, "test.urdf")
    }

    #[test]
    fn revolute_then_mimic_prismatic() {
        let k = chain("").expect("tree");
        assert_eq!(k.variables(), ["j1"]);
        let q = std::f64::consts::FRAC_PI_2;
        let poses = k.link_poses(&[q]);
        let c = poses[2].translation.vector;
        // b at (1,0,0) rotated 90° about z; c slides 2q+0.5 along b's x, which is the root's y.
        assert!((c - Vector3::new(1.0, 2.0 * q + 0.5, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn link_velocities_are_the_derivative_of_the_poses() {
        // A three-joint chain with a mimic prismatic joint: every link point's velocity equals
        // the central difference of its position along q + t·q̇.
        let xml = r#"<robot name="r"><link name="a"/><link name="b"/><link name="c"/><link name="d"/>
            <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
              <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
            <joint name="j2" type="revolute"><parent link="b"/><child link="c"/>
              <origin xyz="0.5 0 0.1" rpy="0 0.4 0"/><axis xyz="0 0.6 0.8"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
            <joint name="j3" type="prismatic"><parent link="c"/><child link="d"/>
              <origin xyz="0 0.3 0"/><axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/>
              <mimic joint="j1" multiplier="-0.5" offset="0.2"/></joint></robot>"#;
        let k = Kinematics::from_urdf(&urdf_rs::read_from_string(xml).expect("xml"), "t")
            .expect("tree");
        let q = [0.7, -1.1];
        let q_dot = [0.9, 1.7];
        let poses = k.link_poses(&q);
        let twists = k.link_velocities(&q_dot, &poses);
        let h = 1e-6;
        let at = |t: f64| k.link_poses(&[q[0] + t * q_dot[0], q[1] + t * q_dot[1]]);
        let (plus, minus) = (at(h), at(-h));
        let local = nalgebra::Point3::new(0.2, -0.1, 0.4);
        for link in 0..4 {
            let p = (poses[link] * local).coords;
            let numeric = ((plus[link] * local) - (minus[link] * local)) / (2.0 * h);
            let v = twists[link].at(&p);
            assert!((v - numeric).norm() < 1e-6, "link {link}: {v} vs {numeric}");
        }
        assert_eq!(twists[0], LinkVelocity::default(), "the root does not move");
    }

    #[test]
    fn cycles_and_double_parents_are_refused() {
        let err =
            chain(r#"<joint name="j3" type="fixed"><parent link="c"/><child link="b"/></joint>"#)
                .unwrap_err();
        assert!(err.to_string().contains("two parent joints"), "{err}");
        let xml = r#"<robot name="r"><link name="a"/><link name="b"/>
            <joint name="x" type="fixed"><parent link="a"/><child link="b"/></joint>
            <joint name="y" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"#;
        let err =
            Kinematics::from_urdf(&urdf_rs::read_from_string(xml).expect("xml"), "t").unwrap_err();
        assert!(err.to_string().contains("cycle"), "{err}");
    }

    #[test]
    fn missing_and_unknown_joints_are_errors() {
        let k = chain("").expect("tree");
        assert!(matches!(
            k.values_from_names(&[], None),
            Err(RobotError::MissingJoint(_))
        ));
        assert!(matches!(
            k.values_from_names(&[("nope".into(), 0.0)], Some(0.0)),
            Err(RobotError::UnknownJoint(_))
        ));
    }
}
