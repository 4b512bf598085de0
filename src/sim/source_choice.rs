//! Where a simulation's motion comes from, as a user names it: a scene file, a built-in scene,
//! a trajectory CSV or a motion definition — the file first, the others over it — and how
//! messages name that source.

use std::path::PathBuf;

use super::{SimError, Simulation, SimulationBuilder};

/// The motion source a user named; at most one of `scene` and `trajectory`, and of
/// `trajectory` and `motion_def`, is expected (the command line refuses both).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SourceChoice {
    /// Scene file (TOML); the others override it.
    pub scene_file: Option<PathBuf>,
    /// Built-in scene.
    pub scene: Option<String>,
    /// Trajectory CSV.
    pub trajectory: Option<PathBuf>,
    /// Motion definition (native TOML or gnss-ins-sim CSV).
    pub motion_def: Option<PathBuf>,
}

impl SourceChoice {
    /// Whether any source was named.
    pub fn given(&self) -> bool {
        self.scene_file.is_some()
            || self.scene.is_some()
            || self.trajectory.is_some()
            || self.motion_def.is_some()
    }

    /// How messages name the source: the most specific one given, else the default scene.
    pub fn name(&self) -> String {
        if let Some(m) = &self.motion_def {
            return format!("motion definition {}", m.display());
        }
        match (&self.trajectory, &self.scene, &self.scene_file) {
            (Some(t), _, _) => format!("trajectory file {}", t.display()),
            (None, Some(n), _) => format!("scene {n}"),
            (None, None, Some(f)) => format!("scene file {}", f.display()),
            (None, None, None) => format!("scene {}", crate::scenes::DEFAULT),
        }
    }

    /// The builder of the scene file (if any) with the scene, trajectory or motion
    /// definition over it.
    pub fn builder(&self) -> Result<SimulationBuilder, SimError> {
        let mut b = match &self.scene_file {
            Some(p) => Simulation::from_scene_file(p)?,
            None => Simulation::builder(),
        };
        if let Some(s) = &self.scene {
            b = b.scene(s);
        }
        if let Some(t) = &self.trajectory {
            b = b.trajectory(t);
        }
        if let Some(m) = &self.motion_def {
            b = b.motion_def(m);
        }
        Ok(b)
    }

    /// The motion to sample at `rate` (Hz) and its grid (samples at t₀ + k/rate for k =
    /// 0..=count): a single unit's run, or a rig's motion over its span (the states to feed a
    /// rig with `run --motion`); `start` and `duration` override the scene file's.
    pub fn reference(
        &self,
        rate: f64,
        start: Option<f64>,
        duration: Option<f64>,
    ) -> Result<(crate::source::AnyMotion, crate::engine::Grid), SimError> {
        let mut b = self.builder()?.rate(rate);
        if let Some(s) = start {
            b = b.start(s);
        }
        if let Some(d) = duration {
            b = b.duration(d);
        }
        Ok(if b.is_rig() {
            let rig = b.build_rig()?;
            let (t0, t1) = rig.span();
            let count = ((t1 - t0) * rate + 1e-9).floor() as u64;
            let grid = crate::engine::Grid {
                t0,
                rate_hz: rate,
                count,
            };
            (rig.motion().clone(), grid)
        } else {
            let sim = b.build()?;
            (sim.motion().clone(), sim.grid())
        })
    }
}
