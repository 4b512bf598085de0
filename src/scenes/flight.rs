//! An aircraft-like analytic scene: a horizontal path in a local map plane, a height profile,
//! and an attitude that follows the motion (heading along the track, pitch along the flight
//! path, bank of a coordinated turn, optionally plus a roll oscillation).
//!
//! The map plane is tied to the ellipsoid by lat = φ₀ + x/(M₀+h₀), lon = λ₀ + y/((N₀+h₀)cos φ₀):
//! every quantity — position, v^n, v̇^n, attitude, ω_nb^b — is then a closed-form function of
//! time, evaluated exactly. The price is that map speeds are ground speeds only to ~1e-4
//! relative away from the origin; along meridians (y constant) the heading is exact.

use super::path::{Jet, Planar, Poly};
use crate::earth::{self, E2};
use crate::kinematics::{NedState, Sensed, sense_ned};
use crate::math::{Mat3, Vec3, dcm_from_euler_sc, omega_from_euler_rates, quat_from_euler};
use crate::motion::{Motion, Pose};

/// One smooth piece: a planar path piece and a height polynomial, with their own time origins.
#[derive(Clone, Copy, Debug)]
pub struct FlightPiece {
    /// Start time of the piece (s).
    pub t_start: f64,
    /// Horizontal motion and the time its local τ counts from.
    pub planar: (Planar, f64),
    /// Height and the time its local τ counts from.
    pub height: (Poly, f64),
}

/// An analytic flight: pieces, the map origin, and an optional roll oscillation.
#[derive(Clone, Debug)]
pub struct FlightScene {
    lat0: f64,
    lon0: f64,
    sin_lat0: f64,
    cos_lat0: f64,
    inv_mh0: f64,
    inv_nh0c: f64,
    inv_g0: f64,
    pieces: Vec<FlightPiece>,
    end: f64,
    roll_osc: Option<(f64, f64)>,
}

impl FlightScene {
    /// Builds a flight from map origin (rad, rad, m), merged pieces and the end time.
    /// `roll_osc` = (amplitude rad, angular frequency rad/s) added to the coordinated bank.
    pub fn new(
        lat0: f64,
        lon0: f64,
        h_ref: f64,
        pieces: Vec<FlightPiece>,
        end: f64,
        roll_osc: Option<(f64, f64)>,
    ) -> FlightScene {
        let s0 = lat0.sin();
        FlightScene {
            lat0,
            lon0,
            sin_lat0: s0,
            cos_lat0: lat0.cos(),
            inv_mh0: 1.0 / (earth::radius_meridian(s0) + h_ref),
            inv_nh0c: 1.0 / ((earth::radius_prime_vertical(s0) + h_ref) * lat0.cos()),
            inv_g0: 1.0 / earth::normal_gravity(s0, h_ref),
            pieces,
            end,
            roll_osc,
        }
    }

    /// Merges independent lists of planar and height pieces (each sorted by start time, the
    /// first starting at `start`) into pieces that are smooth in both. Linear in the number
    /// of pieces: one cursor per list moves forward with the sorted start times.
    pub fn merge(planar: &[(f64, Planar)], height: &[(f64, Poly)]) -> Vec<FlightPiece> {
        let mut starts: Vec<f64> = planar
            .iter()
            .map(|p| p.0)
            .chain(height.iter().map(|h| h.0))
            .collect();
        starts.sort_by(f64::total_cmp);
        starts.dedup();
        // The last piece of `list` starting at or before t (the first if none does), with
        // `i` that piece's index from the previous, earlier t.
        fn current<T>(list: &[(f64, T)], i: &mut usize, t: f64) -> usize {
            while *i + 1 < list.len() && list[*i + 1].0 <= t {
                *i += 1;
            }
            *i
        }
        let (mut ip, mut ih) = (0, 0);
        starts
            .into_iter()
            .map(|t| {
                let p = &planar[current(planar, &mut ip, t)];
                let h = &height[current(height, &mut ih, t)];
                FlightPiece {
                    t_start: t,
                    planar: (p.1, p.0),
                    height: (h.1, h.0),
                }
            })
            .collect()
    }

    /// Map-plane jets (x, y) and height jet at t on piece i.
    #[inline]
    fn jets(&self, i: usize, t: f64) -> (Jet, Jet, Jet) {
        let p = &self.pieces[i];
        let (x, y) = p.planar.0.jets(t - p.planar.1);
        let h = p.height.0.jet(t - p.height.1);
        (x, y, h)
    }

    /// Roll, pitch, yaw as (sin, cos) pairs and the Euler-angle rates, at t.
    #[inline]
    fn attitude(&self, t: f64, x: &Jet, y: &Jet, h: &Jet) -> ([f64; 6], Vec3) {
        // Divisions and square roots dominate the cost here: take each reciprocal once.
        let vh2 = x[1] * x[1] + y[1] * y[1];
        let inv_vh = 1.0 / vh2.sqrt();
        let vh = vh2 * inv_vh;
        let (cy, sy) = (x[1] * inv_vh, y[1] * inv_vh);
        let v2 = vh2 + h[1] * h[1];
        let inv_v = 1.0 / v2.sqrt();
        let (cp, sp) = (vh * inv_v, h[1] * inv_v);
        let cross = x[1] * y[2] - y[1] * x[2];
        let tan_b = cross * inv_vh * self.inv_g0;
        let cb = 1.0 / (1.0 + tan_b * tan_b).sqrt();
        let sb = tan_b * cb;
        let inv_vh2 = inv_vh * inv_vh;
        let psi_dot = cross * inv_vh2;
        let vh_dot = (x[1] * x[2] + y[1] * y[2]) * inv_vh;
        let theta_dot = (vh * h[2] - h[1] * vh_dot) * inv_v * inv_v;
        let alat_dot = ((x[1] * y[3] - y[1] * x[3]) - cross * vh_dot * inv_vh) * inv_vh;
        let mut phi_dot = alat_dot * self.inv_g0 * cb * cb;
        let (mut sr, mut cr) = (sb, cb);
        if let Some((amp, w)) = self.roll_osc {
            let (s, c) = (w * t).sin_cos();
            let (sd, cd) = (amp * s).sin_cos();
            sr = sb * cd + cb * sd;
            cr = cb * cd - sb * sd;
            phi_dot += amp * w * c;
        }
        (
            [sr, cr, sp, cp, sy, cy],
            Vec3::new(phi_dot, theta_dot, psi_dot),
        )
    }

    /// sin and cos of φ₀ + δ. Scenes stay within tens of km of their origin, where δ is small
    /// and a Taylor series (error δ¹¹/11! < 1e-26 for |δ| < 0.02) beats a library sin_cos.
    #[inline]
    fn sin_cos_lat(&self, d: f64) -> (f64, f64) {
        if d.abs() >= 0.02 {
            return (self.lat0 + d).sin_cos();
        }
        let d2 = d * d;
        // Multiplications by reciprocals: a division by a constant is not folded by the compiler.
        const S: [f64; 5] = [1.0 / 6.0, 1.0 / 20.0, 1.0 / 42.0, 1.0 / 72.0, 1.0 / 110.0];
        const C: [f64; 5] = [1.0 / 2.0, 1.0 / 12.0, 1.0 / 30.0, 1.0 / 56.0, 1.0 / 90.0];
        let sd = d
            * (1.0
                - d2 * S[0]
                    * (1.0
                        - d2 * S[1] * (1.0 - d2 * S[2] * (1.0 - d2 * S[3] * (1.0 - d2 * S[4])))));
        let cd = 1.0
            - d2 * C[0]
                * (1.0 - d2 * C[1] * (1.0 - d2 * C[2] * (1.0 - d2 * C[3] * (1.0 - d2 * C[4]))));
        (
            self.sin_lat0 * cd + self.cos_lat0 * sd,
            self.cos_lat0 * cd - self.sin_lat0 * sd,
        )
    }

    /// The NED state (v^n and v̇^n by the chain rule through the radii of curvature) and the
    /// longitude, at t on piece i.
    #[inline]
    fn ned_state(&self, i: usize, t: f64) -> (NedState, f64) {
        let (x, y, h) = self.jets(i, t);
        let (s, c) = self.sin_cos_lat(x[0] * self.inv_mh0);
        let (lat_d, lat_dd) = (x[1] * self.inv_mh0, x[2] * self.inv_mh0);
        let (lon_d, lon_dd) = (y[1] * self.inv_nh0c, y[2] * self.inv_nh0c);
        let ([sr, cr, sp, cp, sy, cy], rates) = self.attitude(t, &x, &y, &h);
        let state = ned_state_from(
            (s, c),
            [lat_d, lat_dd],
            [lon_d, lon_dd],
            &h,
            dcm_from_euler_sc(sr, cr, sp, cp, sy, cy),
            omega_from_euler_rates(sr, cr, sp, cp, rates),
        );
        (state, self.lon0 + y[0] * self.inv_nh0c)
    }
}

/// The NED state of a vehicle whose geodetic position moves with rates `lat` = [φ̇, φ̈],
/// `lon` = [λ̇, λ̈] and height jet `h`: v^n and v̇^n by the chain rule through the radii of
/// curvature, R_N and R_E of WGS-84 and their latitude derivatives
/// dR_N/dφ = 3e²R_N sinφ cosφ/(1 − e²sin²φ), dR_E/dφ = e²R_E sinφ cosφ/(1 − e²sin²φ).
#[inline]
pub(crate) fn ned_state_from(
    (s, c): (f64, f64),
    [lat_d, lat_dd]: [f64; 2],
    [lon_d, lon_dd]: [f64; 2],
    h: &Jet,
    c_b_n: Mat3,
    omega_nb_b: Vec3,
) -> NedState {
    let w = 1.0 - E2 * s * s;
    let inv_w = 1.0 / w;
    let inv_sqrt_w = inv_w.sqrt();
    let re = earth::A * inv_sqrt_w;
    let rn = re * (1.0 - E2) * inv_w;
    let (rn_h, re_h) = (rn + h[0], re + h[0]);
    let scw = s * c * inv_w * lat_d;
    let drn = 3.0 * E2 * rn * scw;
    let dre = E2 * re * scw;
    NedState {
        sin_lat: s,
        cos_lat: c,
        h: h[0],
        r_n: rn,
        r_e: re,
        gravity: earth::normal_gravity_from(s * s, inv_sqrt_w, h[0]),
        v_n: Vec3::new(rn_h * lat_d, re_h * c * lon_d, -h[1]),
        v_dot_n: Vec3::new(
            (drn + h[1]) * lat_d + rn_h * lat_dd,
            ((dre + h[1]) * c - re_h * s * lat_d) * lon_d + re_h * c * lon_dd,
            -h[2],
        ),
        c_b_n,
        omega_nb_b,
    }
}

impl Motion for FlightScene {
    fn start(&self) -> f64 {
        self.pieces[0].t_start
    }
    fn end(&self) -> f64 {
        self.end
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        let ps = &self.pieces;
        let last = ps.len() - 1;
        let h = hint.min(last);
        if ps[h].t_start <= t && (h == last || t < ps[h + 1].t_start) {
            return h;
        }
        ps.partition_point(|p| p.t_start <= t).saturating_sub(1)
    }
    fn piece_end(&self, piece: usize) -> f64 {
        self.pieces
            .get(piece + 1)
            .map_or(f64::INFINITY, |p| p.t_start)
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        sense_ned(&self.ned_state(piece, t).0)
    }
    fn pose(&self, t: f64) -> Pose {
        let i = self.piece_at(t, 0);
        let (s, lon) = self.ned_state(i, t);
        let (x, y, h) = self.jets(i, t);
        let ([sr, cr, sp, cp, sy, cy], _) = self.attitude(t, &x, &y, &h);
        Pose {
            t,
            lat: s.sin_lat.atan2(s.cos_lat),
            lon,
            h: s.h,
            v_n: s.v_n,
            q_b_n: quat_from_euler(sr.atan2(cr), sp.atan2(cp), sy.atan2(cy)),
        }
    }
}
