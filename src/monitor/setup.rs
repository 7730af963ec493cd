//! Starting a monitor: the robot (from a file, URDF text, or a model given), the config's
//! attached objects joined to it, its inner sphere trees built or loaded from the cache, the
//! query engine, and input buffers holding only what the config states (static transforms,
//! fixed joints). Every error here is a start-up error naming the parameter, file, link or
//! frame at fault. A change of attached objects at run time starts a monitor the same way, from
//! the robot without them, and hands it the inputs received so far (`Monitor::take_inputs`).

use crate::config::{Config, RobotSource};
use crate::ist::{self, cache::TreeCache, LinkTree};
use crate::query::{Engine, QueryError};
use crate::robot::RobotModel;
use crate::separation::SpeedScaler;
use crate::tf::{JointError, JointStateBuffer, TfBuffer, TfError};

use super::level::LevelTracker;
use super::pipeline::{Base, Monitor};
use super::source::Source;
use super::unseen::UnseenSpace;

/// A monitor that cannot start: each names the parameter, file, link or frame at fault.
#[derive(Debug, thiserror::Error)]
pub enum MonitorError {
    #[error(transparent)]
    Config(#[from] crate::config::ConfigError),
    #[error("loading robot {urdf}: {source}")]
    Robot {
        urdf: std::path::PathBuf,
        source: crate::robot::RobotError,
    },
    #[error("parameter attached_objects: {0}: {1}")]
    Attached(String, crate::robot::RobotError),
    #[error("inner sphere trees: {0}")]
    Trees(#[from] crate::ist::IstError),
    #[error("query: {0}")]
    Query(#[from] QueryError),
    #[error("parameter static_transforms: {parent} → {child}: {source}")]
    StaticTransform {
        parent: String,
        child: String,
        source: TfError,
    },
    #[error("parameter fixed_joint_state.names: {0}")]
    FixedJoint(JointError),
    #[error(
        "robot_description_topic {0}: only the live node reads the robot from a topic (set \
         robot_description for replay and the command line)"
    )]
    FromTopic(String),
    #[error(
        "the refined trees are not for the monitored links and attached objects (they changed \
         while the trees were built)"
    )]
    Refined,
}

/// The trees of a monitor started on coarse ones ([`Monitor::with_model_first`]), to build on a
/// thread of their own and hand to [`Monitor::swap_trees`].
pub struct Refinement {
    model: RobotModel,
    selection: crate::robot::LinkSelection,
    options: ist::BuildOptions,
    cache_dir: Option<std::path::PathBuf>,
    /// The attached objects the trees are for.
    pub attached: Vec<crate::robot::AttachedObject>,
}

impl Refinement {
    /// Builds (or loads) the selected links' trees at the config's options, caching them;
    /// `built` is called with each link's name as its tree is ready.
    pub fn build(&self, built: &(dyn Fn(&str) + Sync)) -> Result<Vec<LinkTree>, ist::IstError> {
        let cache = TreeCache::at(self.cache_dir.as_deref());
        let selected = |name: &str| self.selection.selects(name);
        Ok(
            ist::build_links(&self.model, &selected, &self.options, Some(&cache), built)?
                .into_iter()
                .map(|(t, _)| t)
                .collect(),
        )
    }
}

impl Monitor {
    /// Loads the robot, builds (or loads from the cache) its trees and applies the config's
    /// static transforms and fixed joints; `built` is called with each link's name as its tree
    /// is ready. Errors here are start-up errors.
    pub fn new(config: Config, built: &(dyn Fn(&str) + Sync)) -> Result<Self, MonitorError> {
        let model = Self::model(&config)?;
        Self::with_model(config, model, built)
    }

    /// The robot of the config's `robot_description` (a file or the URDF text; a topic is an
    /// error: only the node reads one).
    pub fn model(config: &Config) -> Result<RobotModel, MonitorError> {
        match config.robot_source()? {
            RobotSource::File(urdf) => {
                RobotModel::load(&urdf, &config.package_paths, &config.selection)
                    .map_err(|source| MonitorError::Robot { urdf, source })
            }
            RobotSource::Text(xml) => Self::model_from_text(config, &xml, "robot_description"),
            RobotSource::Topic(topic) => Err(MonitorError::FromTopic(topic)),
        }
    }

    /// The robot of URDF text that came from `from` (the parameter or the topic): relative
    /// mesh paths from the current folder, `package://` as for a file.
    pub fn model_from_text(
        config: &Config,
        xml: &str,
        from: &str,
    ) -> Result<RobotModel, MonitorError> {
        let urdf = std::path::PathBuf::from(from);
        RobotModel::from_text(
            xml,
            &urdf,
            std::path::Path::new("."),
            &config.package_paths,
            &config.selection,
        )
        .map_err(|source| MonitorError::Robot { urdf, source })
    }

    /// As [`Monitor::new`], with the robot loaded.
    pub fn with_model(
        config: Config,
        model: RobotModel,
        built: &(dyn Fn(&str) + Sync),
    ) -> Result<Self, MonitorError> {
        Ok(Self::with_model_first(config, model, built, false)?.0)
    }

    /// As [`Monitor::with_model`]; with `coarse_first`, where some selected link's tree is not
    /// in the cache and the budget may grow (`BuildOptions::coarse`), every link gets a coarse
    /// tree first (a fixed budget of `start_spheres`, validated like any, its larger h
    /// certified and reported), and the [`Refinement`] returned builds the trees of the
    /// config's options, for [`Monitor::swap_trees`].
    pub fn with_model_first(
        config: Config,
        mut model: RobotModel,
        built: &(dyn Fn(&str) + Sync),
        coarse_first: bool,
    ) -> Result<(Self, Option<Refinement>), MonitorError> {
        // The robot as it is, for a change of attached objects: a copy only where some join it.
        let base = if config.attached_objects.is_empty() {
            Base::Model
        } else {
            Base::Detached(model.clone())
        };
        for object in &config.attached_objects {
            model
                .attach(object)
                .map_err(|e| MonitorError::Attached(object.name.clone(), e))?;
        }
        // The selection is checked before any tree is built (a robot with too many links, or a
        // misspelt link, is refused at once), and only the selected links are built.
        config.selection.check(&model)?;
        let cache = TreeCache::at(config.cache_dir.as_deref());
        let selected = |name: &str| config.selection.selects(name);
        let coarse = coarse_first
            .then(|| config.build.coarse())
            .flatten()
            .filter(|_| {
                (model.links.iter())
                    .filter(|l| selected(&l.name))
                    .any(|l| !cache.holds(&ist::cache::key(l, &config.build)))
            });
        let options = coarse.as_ref().unwrap_or(&config.build);
        let trees: Vec<LinkTree> =
            ist::build_links(&model, &selected, options, Some(&cache), built)?
                .into_iter()
                .map(|(t, _)| t)
                .collect();
        let refinement = coarse.map(|_| Refinement {
            model: model.clone(),
            selection: config.selection.clone(),
            options: config.build.clone(),
            cache_dir: config.cache_dir.clone(),
            attached: config.attached_objects.clone(),
        });
        let mut monitor = Self::with_trees(config, model, &trees)?;
        monitor.base = base;
        Ok((monitor, refinement))
    }

    /// Replaces the trees of the monitored links by `trees` (those of a [`Refinement`]): a new
    /// query engine over the same robot, links and options; inputs, sources, levels and the
    /// speed scaler stay as they are, so monitoring goes on without a gap. Trees for other
    /// links, or for a robot whose attached objects changed since, are refused.
    pub fn swap_trees(
        &mut self,
        trees: &[LinkTree],
        attached: &[crate::robot::AttachedObject],
    ) -> Result<(), MonitorError> {
        let names = |links: &[crate::query::QueryLink]| -> Vec<String> {
            links.iter().map(|l| l.name.clone()).collect()
        };
        let mut engine = Engine::new(&self.model, trees, &self.config.selection)?;
        if attached != self.config.attached_objects.as_slice()
            || names(engine.links()) != names(self.engine.links())
        {
            return Err(MonitorError::Refined);
        }
        engine.prepare_self_filter(&self.config.query);
        if self.config.query.backend != crate::query::Backend::Cpu {
            engine.gpu();
        }
        self.engine = engine;
        Ok(())
    }

    /// The robot without its attached objects: what the monitor of a change of them is built
    /// from ([`Monitor::with_model`], on a thread of its own; the trees of the robot's links come
    /// from the cache). `None` for a monitor made from a model with its objects already attached
    /// ([`Monitor::with_trees`]).
    pub fn robot_without_objects(&self) -> Option<RobotModel> {
        match &self.base {
            Base::Model => Some(self.model.clone()),
            Base::Detached(model) => Some(model.clone()),
            Base::Unknown => None,
        }
    }

    /// Takes over the inputs `old` received (transforms, joint states, camera models), up to
    /// the moment it is replaced: a `/tf_static` that arrived while this monitor was built is
    /// kept. Its levels start anew: every source is in fault until its next frame; the node's
    /// watch of each source (heard from, silent since when) goes on as it was.
    pub fn take_inputs(&mut self, old: &mut Monitor) {
        std::mem::swap(&mut self.tf, &mut old.tf);
        std::mem::swap(&mut self.joints, &mut old.joints);
        if old.sources.len() == self.sources.len() {
            for (new, old) in self.sources.iter_mut().zip(&mut old.sources) {
                new.take_inputs(old);
            }
        }
    }

    /// Forgets every transform, joint state and level received, as at start-up (a replay of
    /// another bag starts from here).
    pub fn reset(&mut self) -> Result<(), MonitorError> {
        (self.tf, self.joints) = Self::inputs(&self.config, &self.model)?;
        self.sources = Self::sources(&self.config);
        self.fused = LevelTracker::new(&self.config);
        self.scaler = Self::scaler(&self.config);
        Ok(())
    }

    /// As [`Monitor::new`], with the model and trees given (the model with the config's
    /// attached objects attached).
    pub fn with_trees(
        config: Config,
        model: RobotModel,
        trees: &[LinkTree],
    ) -> Result<Self, MonitorError> {
        for object in &config.attached_objects {
            if model.kinematics.link_index(&object.name).is_none() {
                return Err(MonitorError::Attached(
                    object.name.clone(),
                    crate::robot::RobotError::Topology {
                        path: model.urdf_path.display().to_string(),
                        message: "not attached to the model the trees were built for".into(),
                    },
                ));
            }
        }
        config.query.validate()?;
        let mut engine = Engine::new(&model, trees, &config.selection)?;
        // The self-filter's grids now, not on the first cloud.
        engine.prepare_self_filter(&config.query);
        let (tf, joints) = Self::inputs(&config, &model)?;
        Ok(Self {
            sources: Self::sources(&config),
            fused: LevelTracker::new(&config),
            scaler: Self::scaler(&config),
            unseen: UnseenSpace::new(&config),
            config,
            model,
            engine,
            tf,
            joints,
            depth_points: Vec::new(),
            base: Base::Unknown,
        })
    }

    /// Empty input buffers, holding only what the config states (static transforms, fixed
    /// joints).
    pub(super) fn inputs(
        config: &Config,
        model: &RobotModel,
    ) -> Result<(TfBuffer, JointStateBuffer), MonitorError> {
        let mut tf = TfBuffer::new(10.0);
        tf.set_voice_window(config.second_publisher_window_s);
        for t in &config.static_transforms {
            tf.insert(t, true)
                .map_err(|source| MonitorError::StaticTransform {
                    parent: t.header.frame_id.clone(),
                    child: t.child_frame_id.clone(),
                    source,
                })?;
        }
        let mut joints = JointStateBuffer::new(model.kinematics.variables());
        joints.set_voice_window(config.second_publisher_window_s);
        joints
            .set_fixed(&config.fixed_joint_state)
            .map_err(MonitorError::FixedJoint)?;
        Ok((tf, joints))
    }

    /// The config's sources, each never heard from.
    fn sources(config: &Config) -> Vec<Source> {
        config.sources.iter().map(|_| Source::new(config)).collect()
    }

    /// The speed scaler of the config's sources, each starting at 0.
    pub(super) fn scaler(config: &Config) -> SpeedScaler {
        let enabled: Vec<bool> = config.sources.iter().map(|s| s.enabled).collect();
        SpeedScaler::new(&config.ssm, &enabled)
    }
}
