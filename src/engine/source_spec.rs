//! Where a run's trajectory comes from, and the motion model built from it.

use std::path::PathBuf;

use crate::motion::sampled::ModelSettings;
use crate::scenes::{self, SceneParams};
use crate::source::AnyMotion;
use crate::trajectory;

use super::EngineError;

/// Where the trajectory comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum SourceSpec {
    /// A built-in scene with its parameters.
    Scene(String, SceneParams),
    /// A trajectory CSV.
    File(PathBuf),
    /// A motion-definition file (gnss-ins-sim CSV).
    MotionDef(PathBuf),
    /// Trajectory samples held in memory (checked as a trajectory file's rows are), named by
    /// `label` in messages: for callers that have the trajectory as arrays (Python).
    Samples {
        /// What the samples are, for messages (`trajectory arrays`).
        label: PathBuf,
        /// The samples, in time order.
        samples: std::sync::Arc<Vec<crate::motion::sampled::Sample>>,
    },
}

/// Builds the motion model of a source.
pub fn build_motion(source: &SourceSpec, model: ModelSettings) -> Result<AnyMotion, EngineError> {
    match source {
        SourceSpec::Scene(name, params) => Ok(AnyMotion::Scene(scenes::build(name, params)??)),
        SourceSpec::File(path) => Ok(AnyMotion::Sampled(trajectory::open_motion(path, model)?)),
        SourceSpec::MotionDef(path) => Ok(AnyMotion::Defined(crate::motiondef::open(path)?)),
        SourceSpec::Samples { label, samples } => {
            let m =
                crate::motion::sampled::SampledMotion::new(samples, model).map_err(|source| {
                    EngineError::Model {
                        path: label.clone(),
                        source,
                    }
                })?;
            Ok(AnyMotion::Sampled(m))
        }
    }
}
