//! The motion a run evaluates: a built-in analytic scene, a sampled trajectory, a motion
//! definition or a live stream of states.

use crate::kinematics::Sensed;
use crate::motion::causal::CausalMotion;
use crate::motion::sampled::SampledMotion;
use crate::motion::{Motion, Pose};
use crate::motiondef::DefinedMotion;
use crate::scenes::Scene;

/// Any motion model, dispatched by a `match` (cheaper than a trait object in the hot loop and
/// keeps the generator monomorphic).
#[derive(Clone, Debug)]
pub enum AnyMotion {
    /// A built-in scene.
    Scene(Scene),
    /// A trajectory file.
    Sampled(SampledMotion),
    /// States arriving live (a shared handle: the input side keeps pushing into it).
    Live(CausalMotion),
    /// A motion definition.
    Defined(DefinedMotion),
}

macro_rules! each {
    ($self:ident, $m:ident => $e:expr) => {
        match $self {
            AnyMotion::Scene(Scene::Fixed($m)) => $e,
            AnyMotion::Scene(Scene::Flight($m)) => $e,
            AnyMotion::Scene(Scene::Polar($m)) => $e,
            AnyMotion::Sampled($m) => $e,
            AnyMotion::Live($m) => $e,
            AnyMotion::Defined($m) => $e,
        }
    };
}

impl AnyMotion {
    /// The motion definition's GNSS visibility flags, when the motion is one (other motions
    /// have none: GNSS is always visible).
    pub fn defined(&self) -> Option<&DefinedMotion> {
        match self {
            AnyMotion::Defined(m) => Some(m),
            _ => None,
        }
    }
}

impl Motion for AnyMotion {
    fn start(&self) -> f64 {
        each!(self, m => m.start())
    }
    fn end(&self) -> f64 {
        each!(self, m => m.end())
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        each!(self, m => m.piece_at(t, hint))
    }
    fn piece_end(&self, piece: usize) -> f64 {
        each!(self, m => m.piece_end(piece))
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        each!(self, m => m.sense(piece, t))
    }
    fn pose(&self, t: f64) -> Pose {
        each!(self, m => m.pose(t))
    }
    fn is_stationary(&self) -> bool {
        each!(self, m => m.is_stationary())
    }
}
