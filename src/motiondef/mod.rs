//! Motion definitions: a trip described as a list of manoeuvres (gnss-ins-sim's
//! motion-definition CSV, [`gnss_ins_sim`]), turned into a motion model that is exact to
//! round-off.
//!
//! The commands prescribe the ZYX Euler angles and the body-frame velocity as piecewise
//! polynomials ([`profile`]). The attitude is evaluated from those polynomials directly. The
//! position is a chain of quintic polynomials in latitude, longitude and height, one per
//! knot interval of at most [`KNOT_S`], each matching at both knots the prescribed position
//! (integrated with 4th-order Runge–Kutta in 20 ms steps), velocity C_b^n·v^b and
//! acceleration C_b^n·(ω_nb^b × v^b + v̇^b). Velocity and acceleration are then those
//! polynomials' exact derivatives (chain rule through the radii of curvature), so the truth
//! and the ideal IMU signal are consistent to round-off and continuous in every derivative
//! the IMU senses; between knots the body velocity differs from the prescribed one only by
//! the quintic's interpolation error (≈ v·ω⁵·Δt⁶/46080, micrometres per second at 2 rad/s).

pub mod gnss_ins_sim;
pub mod native;
pub mod profile;
pub mod waypoints;

use std::path::Path;

use crate::csvio::FileError;
use crate::earth::{self, E2};
use crate::kinematics::{Sensed, sense_ned};
use crate::math::{Mat3, Vec3, dcm_from_euler_sc, omega_from_euler_rates, quat_from_euler};
use crate::motion::{Motion, Pose};
use crate::scenes::flight::ned_state_from;
use crate::scenes::path::{Jet, Poly};
use profile::Piece;

/// Longest knot interval of the position polynomials (s).
pub const KNOT_S: f64 = 0.25;

/// Runge–Kutta step of the knot positions (s): its error, O(step⁴), stays below 1e-12 m per
/// knot interval for the speeds and rates of the limits.
const RK_STEP_S: f64 = 0.02;

/// One command of a motion definition, for messages and the truth output.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    /// Line of the command in its file.
    pub line: u64,
    /// Start and end time (s).
    pub span: (f64, f64),
    /// Whether GNSS is visible during it (gnss-ins-sim's last column).
    pub gnss_visible: bool,
}

/// A knot interval: position polynomials and the prescribed piece it lies in. Latitude and
/// longitude are a base plus a polynomial of the change from it: in absolute radians the
/// quintic's coefficients would cancel at the ulp of the angle (0.7 nm), which divided by a
/// quarter-second interval is a velocity error of 1e-8 m/s.
#[derive(Clone, Copy, Debug)]
struct Knot {
    t0: f64,
    lat0: f64,
    lon0: f64,
    lat: Poly,
    lon: Poly,
    h: Poly,
    piece: usize,
}

/// A motion definition, ready to evaluate.
#[derive(Clone, Debug)]
pub struct DefinedMotion {
    knots: Vec<Knot>,
    pieces: Vec<Piece>,
    segments: Vec<Segment>,
    end: f64,
}

/// Attitude and its rate on a prescribed piece at τ: (C_b^n, ω_nb^b, (sin, cos) of roll,
/// pitch, yaw).
#[inline]
fn attitude(p: &Piece, tau: f64) -> (Mat3, Vec3, [f64; 3]) {
    let [y, pt, r] = [0, 1, 2].map(|k| p.poly[k].jet(tau));
    let (sr, cr) = r[0].sin_cos();
    let (sp, cp) = pt[0].sin_cos();
    let (sy, cy) = y[0].sin_cos();
    (
        dcm_from_euler_sc(sr, cr, sp, cp, sy, cy),
        omega_from_euler_rates(sr, cr, sp, cp, Vec3::new(r[1], pt[1], y[1])),
        [r[0], pt[0], y[0]],
    )
}

/// Prescribed v^n and v̇^n on piece p at τ.
pub(crate) fn prescribed(p: &Piece, tau: f64) -> (Vec3, Vec3) {
    let (c, w, _) = attitude(p, tau);
    let [x, y, z] = [3, 4, 5].map(|k| p.poly[k].jet(tau));
    let v_b = Vec3::new(x[0], y[0], z[0]);
    let a_b = Vec3::new(x[1], y[1], z[1]) + w.cross(&v_b);
    (c * v_b, c * a_b)
}

/// (φ̇, λ̇, ḣ) at a geodetic position for NED velocity v.
fn geo_rates(lat: f64, h: f64, v: Vec3) -> [f64; 3] {
    let (s, c) = lat.sin_cos();
    let m = earth::radius_meridian(s) + h;
    let n = earth::radius_prime_vertical(s) + h;
    [v[0] / m, v[1] / (n * c), -v[2]]
}

/// Jets [value, first, second derivative] of latitude, longitude and height from position,
/// v^n and v̇^n: the inverse of [`ned_state_from`].
fn geo_jets(pos: [f64; 3], v: Vec3, a: Vec3) -> [[f64; 3]; 3] {
    let [lat, lon, h] = pos;
    let (s, c) = lat.sin_cos();
    let w = 1.0 - E2 * s * s;
    let rm = earth::radius_meridian(s);
    let rn = earth::radius_prime_vertical(s);
    let (mh, nh) = (rm + h, rn + h);
    let lat_d = v[0] / mh;
    let lon_d = v[1] / (nh * c);
    let h_d = -v[2];
    let drm = 3.0 * E2 * rm * s * c / w * lat_d;
    let drn = E2 * rn * s * c / w * lat_d;
    let lat_dd = (a[0] - (drm + h_d) * lat_d) / mh;
    let lon_dd = (a[1] - ((drn + h_d) * c - nh * s * lat_d) * lon_d) / (nh * c);
    [[lat, lat_d, lat_dd], [lon, lon_d, lon_dd], [h, h_d, -a[2]]]
}

impl DefinedMotion {
    /// Builds the motion from prescribed pieces, the start position (rad, rad, m) and the
    /// commands' segments.
    pub fn new(origin: [f64; 3], pieces: Vec<Piece>, segments: Vec<Segment>) -> DefinedMotion {
        let mut knots = Vec::new();
        let mut pos = origin;
        for (i, p) in pieces.iter().enumerate() {
            let n = (p.duration / KNOT_S).ceil().max(1.0) as usize;
            let step = p.duration / n as f64;
            for j in 0..n {
                let ta = j as f64 * step;
                let tb = if j + 1 == n { p.duration } else { ta + step };
                let (va, aa) = prescribed(p, ta);
                let mut start = geo_jets(pos, va, aa);
                let base = [pos[0], pos[1]];
                start[0][0] = 0.0;
                start[1][0] = 0.0;
                // The changes of latitude and longitude over the interval, kept apart from
                // their bases so that they keep full relative precision.
                let mut dpos = [0.0, 0.0, pos[2]];
                // Classical Runge–Kutta on (φ, λ, h) with the prescribed velocity.
                let m = ((tb - ta) / RK_STEP_S).ceil().max(1.0) as usize;
                let hstep = (tb - ta) / m as f64;
                for q in 0..m {
                    let t = ta + q as f64 * hstep;
                    let f =
                        |t: f64, y: [f64; 3]| geo_rates(base[0] + y[0], y[2], prescribed(p, t).0);
                    let add = |y: [f64; 3], k: [f64; 3], s: f64| {
                        [y[0] + s * k[0], y[1] + s * k[1], y[2] + s * k[2]]
                    };
                    let k1 = f(t, dpos);
                    let k2 = f(t + 0.5 * hstep, add(dpos, k1, 0.5 * hstep));
                    let k3 = f(t + 0.5 * hstep, add(dpos, k2, 0.5 * hstep));
                    let k4 = f(t + hstep, add(dpos, k3, hstep));
                    for d in 0..3 {
                        dpos[d] += hstep / 6.0 * (k1[d] + 2.0 * k2[d] + 2.0 * k3[d] + k4[d]);
                    }
                }
                pos = [base[0] + dpos[0], base[1] + dpos[1], dpos[2]];
                let (vb, ab) = prescribed(p, tb);
                let mut end = geo_jets(pos, vb, ab);
                end[0][0] = dpos[0];
                end[1][0] = dpos[1];
                let fit = |k: usize| Poly::hermite5(start[k], end[k], tb - ta);
                knots.push(Knot {
                    t0: p.t0 + ta,
                    lat0: base[0],
                    lon0: base[1],
                    lat: fit(0),
                    lon: fit(1),
                    h: fit(2),
                    piece: i,
                });
            }
        }
        let end = pieces.last().map_or(0.0, |p| p.t0 + p.duration);
        DefinedMotion {
            knots,
            pieces,
            segments,
            end,
        }
    }

    /// The commands, with their spans and GNSS visibility.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Whether GNSS is visible at `t` (the flag of the command running then).
    pub fn gnss_visible(&self, t: f64) -> bool {
        let i = self.segments.partition_point(|s| s.span.0 <= t);
        self.segments
            .get(i.saturating_sub(1))
            .is_none_or(|s| s.gnss_visible)
    }

    /// The spans [start, end) in which GNSS is not visible, adjacent commands merged: exactly
    /// the times at which [`DefinedMotion::gnss_visible`] is false. The first command's flag
    /// holds before the start and the last one's after the end, so a span reaching either
    /// opens to ∓`f64::MAX` (finite, as outage windows must be).
    pub fn gnss_outages(&self) -> Vec<[f64; 2]> {
        let mut out: Vec<[f64; 2]> = Vec::new();
        for (i, s) in self.segments.iter().enumerate() {
            if s.gnss_visible {
                continue;
            }
            let end = match self.segments.get(i + 1) {
                Some(next) => next.span.0,
                None => f64::MAX,
            };
            // Before the first command the flag is the first one's (`gnss_visible` defaults to it).
            let start = if i == 0 { -f64::MAX } else { s.span.0 };
            match out.last_mut() {
                _ if start >= end => {}
                Some(w) if w[1] == start => w[1] = end,
                _ => out.push([start, end]),
            }
        }
        out
    }

    /// Checks the specific force against `max_g` times `g` (and, if given, |ω_ib| against
    /// `max_rate` plus the Earth's rate) at the start, middle and end of every knot interval;
    /// a violation returns the index of the segment it falls in and what was exceeded.
    pub(crate) fn check_load(
        &self,
        g: f64,
        max_g: f64,
        max_rate: Option<f64>,
    ) -> Result<(), (usize, String)> {
        for (i, k) in self.knots.iter().enumerate() {
            let end = self.piece_end(i).min(self.end);
            let seg = self.pieces[k.piece].segment;
            for t in [k.t0, 0.5 * (k.t0 + end), end] {
                let s = self.sense(i, t);
                let (n, w) = (s.f_b.norm() / g, s.omega_ib_b.norm());
                if n > max_g || !n.is_finite() {
                    return Err((
                        seg,
                        format!(
                            "the specific force reaches {n:.3} g at t = {t} s, beyond max_g = {max_g}"
                        ),
                    ));
                }
                if let Some(r) = max_rate
                    && (w > r + earth::OMEGA_IE || !w.is_finite())
                {
                    return Err((
                        seg,
                        format!(
                            "the angular rate reaches {:.3}°/s at t = {t} s, beyond \
                             max_rate_deg_s = {}",
                            w.to_degrees(),
                            r.to_degrees()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    #[inline]
    fn jets(&self, i: usize, t: f64) -> (Jet, Jet, Jet) {
        let k = &self.knots[i];
        let tau = t - k.t0;
        (k.lat.jet(tau), k.lon.jet(tau), k.h.jet(tau))
    }

    #[inline]
    fn state(&self, i: usize, t: f64) -> (crate::kinematics::NedState, Jet, [f64; 3]) {
        let (lat, mut lon, h) = self.jets(i, t);
        let k = &self.knots[i];
        let p = &self.pieces[k.piece];
        let (c, w, euler) = attitude(p, t - p.t0);
        let sc = (k.lat0 + lat[0]).sin_cos();
        let st = ned_state_from(sc, [lat[1], lat[2]], [lon[1], lon[2]], &h, c, w);
        lon[0] += k.lon0;
        (st, lon, euler)
    }
}

impl Motion for DefinedMotion {
    fn start(&self) -> f64 {
        self.knots[0].t0
    }
    fn end(&self) -> f64 {
        self.end
    }
    fn piece_at(&self, t: f64, hint: usize) -> usize {
        let ks = &self.knots;
        let last = ks.len() - 1;
        let h = hint.min(last);
        if ks[h].t0 <= t && (h == last || t < ks[h + 1].t0) {
            return h;
        }
        ks.partition_point(|k| k.t0 <= t).saturating_sub(1)
    }
    fn piece_end(&self, piece: usize) -> f64 {
        self.knots.get(piece + 1).map_or(f64::INFINITY, |k| k.t0)
    }
    #[inline]
    fn sense(&self, piece: usize, t: f64) -> Sensed {
        sense_ned(&self.state(piece, t).0)
    }
    fn pose(&self, t: f64) -> Pose {
        let i = self.piece_at(t, 0);
        let (s, lon, [r, p, y]) = self.state(i, t);
        Pose {
            t,
            lat: s.sin_lat.atan2(s.cos_lat),
            lon: lon[0],
            h: s.h,
            v_n: s.v_n,
            q_b_n: quat_from_euler(r, p, y),
        }
    }
}

/// Reads a motion-definition file: the native `[motion]` table of a `.toml` file, else
/// gnss-ins-sim's CSV.
pub fn open(path: &Path) -> Result<DefinedMotion, FileError> {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"))
    {
        native::read(path)
    } else {
        gnss_ins_sim::read(path)
    }
}
