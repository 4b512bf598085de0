//! A candidate unit of a campaign: an error template at a place on the body (the scene's
//! `[imu]` or a rig's `[[imu]]` mounting and lever arm), its records for one seeded run and
//! its own true state (the point it sits at, in its own axes). Pure computation, no I/O.
//!
//! A unit at the reference point in the body's axes gets its records from the engine's
//! [`Producer`] (the records `generate` writes for the template). A placed unit gets the
//! reference point's error-free records turned into its readings the way a rig does
//! ([`crate::rig::geometry`]: the specific force at the lever arm, in the case axes), then the
//! template's error chain. The navigator then follows the unit's own point and axes, so its
//! truth is that point: r + C_b^e l, v + C_b^e (ω_eb^b × l), C_c^e = C_b^e C_c^b (a rigid
//! body; Titterton & Weston, *Strapdown Inertial Navigation Technology*, 2nd ed., §10.4).

use crate::earth::{self, Geodetic};
use crate::engine::{BLOCK, EngineError, Grid, Producer};
use crate::errors::ErrorChain;
use crate::errors::template::ImuModel;
use crate::generator::{DEFAULT_NODES, IdealImu, RotationTerms};
use crate::math::{Quat, QuatExt, Vec3, quat_from_euler};
use crate::motion::Motion;
use crate::nav::strapdown::NavState;
use crate::record::Record;
use crate::rig::geometry::{self, Placement};
use crate::source::AnyMotion;

/// A unit to compare: a template, where it sits, and where its description came from.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The name in the table: the template's, or the rig unit's.
    pub name: String,
    /// The error template.
    pub model: ImuModel,
    /// Record rate (Hz).
    pub rate_hz: f64,
    /// Mounting [roll, pitch, yaw] of the case in the body (deg).
    pub mounting_deg: [f64; 3],
    /// Lever arm from the reference point (body frame, m).
    pub lever_arm_m: [f64; 3],
    /// A rig unit draws its errors from the run seed and its name (as a rig does); a
    /// template shares the run seed with every other template (common random numbers).
    pub rig_unit: bool,
}

impl Candidate {
    /// The seed of this unit's errors in a run whose seed is `run_seed`.
    pub fn seed(&self, run_seed: u64) -> u64 {
        match self.rig_unit {
            true => crate::rng::splitmix64(
                run_seed ^ crate::rng::fnv1a64(&format!("unit/{}", self.name)),
            ),
            false => run_seed,
        }
    }

    fn placement(&self) -> Placement {
        Placement::new(self.mounting_deg, self.lever_arm_m)
    }

    /// Whether the unit sits at the reference point in the body's axes.
    pub fn at_reference(&self) -> bool {
        self.placement().is_identity()
    }

    /// The unit's records over `grid` with errors drawn from `seed`.
    pub fn records(
        &self,
        motion: &AnyMotion,
        grid: Grid,
        seed: u64,
    ) -> Result<UnitRecords, EngineError> {
        if self.at_reference() {
            return Ok(UnitRecords::Engine(Box::new(Producer::for_model(
                motion.clone(),
                grid,
                &self.model,
                seed,
            )?)));
        }
        Ok(UnitRecords::Placed(Box::new(Placed {
            ideal: IdealImu::new(
                motion.clone(),
                grid.rate_hz,
                grid.t0,
                grid.count,
                DEFAULT_NODES,
            ),
            chain: ErrorChain::new(&self.model, grid.rate_hz, seed),
            place: self.placement(),
            dt: 1.0 / grid.rate_hz,
            count: grid.count,
            next: 1,
            recs: Vec::new(),
            rot: Vec::new(),
            rot_case: Vec::new(),
        })))
    }

    /// The true state of the unit (its point, velocity and axes) at `t`.
    pub fn truth(&self, motion: &AnyMotion, t: f64) -> NavState {
        let pose = motion.pose(t);
        let body = NavState::from_pose(&pose);
        if self.at_reference() {
            return body;
        }
        let geo = Geodetic::from_radians(pose.lat, pose.lon, pose.h);
        let c_b_e = body.q_b_e.to_mat();
        let l = Vec3::from(self.lever_arm_m);
        let piece = motion.piece_at(t, 0);
        let w_ib = motion.sense(piece, t).omega_ib_b;
        let w_ie_b =
            c_b_e.transpose() * (geo.c_n_e() * earth::omega_ie_n(geo.sin_lat, geo.cos_lat));
        let [r, p, y] = self.mounting_deg.map(f64::to_radians);
        let q_c_b: Quat = quat_from_euler(r, p, y);
        NavState {
            t,
            r_e: body.r_e + c_b_e * l,
            v_e: body.v_e + c_b_e * (w_ib - w_ie_b).cross(&l),
            q_b_e: (body.q_b_e * q_c_b).normalized(),
        }
    }
}

/// One block of a unit's records: the first record's index (from 1) and the records.
pub struct RecordBlock<'a> {
    /// Index of the first record (record k covers (t₀ + (k−1)/rate, t₀ + k/rate]).
    pub first: u64,
    /// The records.
    pub records: &'a [Record],
}

/// A unit's records for one run, block by block.
pub enum UnitRecords {
    /// At the reference point: the engine's producer.
    Engine(Box<Producer>),
    /// Placed on the body: its readings made here.
    Placed(Box<Placed>),
}

/// The readings of a placed unit: error-free reference records turned into the unit's
/// readings, then its template's errors.
pub struct Placed {
    ideal: IdealImu<AnyMotion>,
    chain: ErrorChain,
    place: Placement,
    dt: f64,
    count: u64,
    next: u64,
    recs: Vec<Record>,
    rot: Vec<RotationTerms>,
    rot_case: Vec<RotationTerms>,
}

impl UnitRecords {
    /// The next block, or `None` at the end of the grid.
    pub fn next_block(&mut self) -> Option<RecordBlock<'_>> {
        match self {
            UnitRecords::Engine(p) => p.next_records(BLOCK).map(|b| RecordBlock {
                first: b.first + 1,
                records: b.records,
            }),
            UnitRecords::Placed(p) => p.next_block(),
        }
    }

    /// Whether every record was finite (the engine's check).
    pub fn finished(&mut self) -> Result<(), EngineError> {
        match self {
            UnitRecords::Engine(p) => p.finished(),
            UnitRecords::Placed(_) => Ok(()),
        }
    }
}

impl Placed {
    fn next_block(&mut self) -> Option<RecordBlock<'_>> {
        if self.next > self.count {
            return None;
        }
        let k = self.next;
        let n = ((self.count - k + 1) as usize).min(BLOCK);
        self.recs.resize(n, Record::default());
        self.ideal.fill(k, &mut self.recs);
        let lever = self.place.lever_b != Vec3::zeros();
        if lever || self.chain.needs_rotation_terms() {
            self.rot.resize(n, RotationTerms::default());
            self.ideal.rotation_terms(k, &mut self.rot);
        }
        for (i, r) in self.recs.iter_mut().enumerate() {
            let f = match lever {
                true => {
                    geometry::force_at(r.accel, &self.rot[i], 1.0 / self.dt, self.place.lever_b)
                }
                false => r.accel,
            };
            r.gyro = self.place.to_case(r.gyro);
            r.accel = self.place.to_case(f);
            r.dtheta = r.gyro * self.dt;
            r.dv = r.accel * self.dt;
        }
        let terms = match self.chain.needs_rotation_terms() {
            true => {
                self.rot_case.clear();
                self.rot_case
                    .extend(self.rot.iter().map(|t| match &self.place.c_b_c {
                        Some(m) => geometry::rotate_terms(t, m),
                        None => *t,
                    }));
                Some(&self.rot_case[..])
            }
            false => None,
        };
        self.chain.apply_with(&mut self.recs, terms);
        self.next += n as u64;
        Some(RecordBlock {
            first: k,
            records: &self.recs,
        })
    }
}
