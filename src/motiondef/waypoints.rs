//! Waypoints with times of arrival (as MATLAB's `waypointTrajectory`): the vehicle is at each
//! waypoint at its time, on a path whose latitude, longitude and height are quintic
//! polynomials of time between waypoints.
//!
//! Each waypoint gets a rate and a second derivative of latitude, longitude and height: the
//! velocity given there (converted to geodetic rates), else the natural cubic spline's through
//! all the waypoints, and always the spline's second derivative. The quintic on each interval
//! matches position, rate and second derivative at both ends, so velocity and acceleration are
//! continuous everywhere and the vehicle passes every waypoint to round-off. The attitude is
//! the natural cubic spline of the Euler angles given at every waypoint, or else follows the
//! velocity (yaw the course, pitch the flight-path angle, roll 0, MATLAB's default); in both
//! cases it is a quintic per knot interval matching angle, rate and second derivative at the
//! knots (differentiated exactly through the geodetic path), so the angular rate is
//! continuous.

use serde::Deserialize;

use super::profile::{CHANNELS, Piece};
use super::{DefinedMotion, KNOT_S, Knot, Segment};
use crate::earth::{self, E2, Geodetic};
use crate::math::Vec3;
use crate::motion::limits;
use crate::scenes::path::{Jet, Poly};

/// One entry of `motion.waypoints`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct WaypointSpec {
    t_s: f64,
    north_m: Option<f64>,
    east_m: Option<f64>,
    down_m: Option<f64>,
    lat_deg: Option<f64>,
    lon_deg: Option<f64>,
    h_m: Option<f64>,
    velocity_m_s: Option<[f64; 3]>,
    yaw_deg: Option<f64>,
    pitch_deg: Option<f64>,
    roll_deg: Option<f64>,
    gnss: Option<bool>,
}

/// The limits a waypoint path is checked against.
pub(super) struct PathLimits {
    /// Largest specific force over the start's normal gravity (g).
    pub max_g: f64,
    /// Largest angular rate magnitude (rad/s).
    pub max_rate: f64,
}

/// A waypoint's failure: its index and message, for the caller to place at its line.
pub(super) type Refusal = (usize, String);

/// Smallest horizontal speed (m/s) at which the heading can follow the velocity.
const MIN_COURSE_SPEED: f64 = 0.01;

/// Builds the path through `wps` (each with its line) from the start position `origin`
/// (rad, rad, m).
pub(super) fn build(
    wps: &[(u64, &WaypointSpec)],
    origin: [f64; 3],
    lim: &PathLimits,
) -> Result<DefinedMotion, Refusal> {
    if wps.len() < 2 {
        return Err((0, "give at least two waypoints".into()));
    }
    let oriented = check(wps)?;
    let times: Vec<f64> = wps.iter().map(|w| w.1.t_s).collect();
    let pos: Vec<[f64; 3]> = wps.iter().map(|w| position(w.1, origin)).collect();
    for (i, p) in pos.iter().enumerate() {
        if !(limits::MIN_HEIGHT_M..=limits::MAX_HEIGHT_M).contains(&p[2]) || p[0].abs() > 1.5 {
            return Err((i, "the position is beyond the kinematics' limits".into()));
        }
    }
    // Rates and second derivatives at the waypoints, per channel.
    let mut jets: Vec<[[f64; 3]; 3]> = vec![[[0.0; 3]; 3]; wps.len()];
    for k in 0..3 {
        let y: Vec<f64> = pos.iter().map(|p| p[k] - pos[0][k]).collect();
        for (i, (d1, d2)) in natural_spline(&times, &y).into_iter().enumerate() {
            jets[i][k] = [pos[i][k], d1, d2];
        }
    }
    for (i, w) in wps.iter().enumerate() {
        if let Some(v) = w.1.velocity_m_s {
            let [lat, _, h] = pos[i];
            let (s, c) = lat.sin_cos();
            let rates = [
                v[0] / (earth::radius_meridian(s) + h),
                v[1] / ((earth::radius_prime_vertical(s) + h) * c),
                -v[2],
            ];
            for k in 0..3 {
                jets[i][k][1] = rates[k];
            }
        }
    }
    let euler = oriented.then(|| euler_jets(wps, &times));
    let mut knots = Vec::new();
    let mut pieces = Vec::new();
    let mut segments = Vec::new();
    let mut last_att: Option<[[f64; 3]; 3]> = None;
    for i in 0..wps.len() - 1 {
        let dt = times[i + 1] - times[i];
        // The interval's quintics, in the change from waypoint i (full relative precision).
        let quintic = |k: usize| {
            let (a, b) = (jets[i][k], jets[i + 1][k]);
            let base = if k == 2 { 0.0 } else { a[0] };
            Poly::hermite5([a[0] - base, a[1], a[2]], [b[0] - base, b[1], b[2]], dt)
        };
        let q = [quintic(0), quintic(1), quintic(2)];
        let n = (dt / KNOT_S).ceil().max(1.0) as usize;
        let step = dt / n as f64;
        for j in 0..n {
            let ta = j as f64 * step;
            let tb = if j + 1 == n { dt } else { ta + step };
            let (ja, jb) = (q.map(|p| p.jet(ta)), q.map(|p| p.jet(tb)));
            let fit = |k: usize| {
                let (a, b) = (ja[k], jb[k]);
                Poly::hermite5([a[0], a[1], a[2]], [b[0], b[1], b[2]], tb - ta)
            };
            let att = |tau: f64, jet: &[Jet; 3]| match &euler {
                Some(e) => Ok(e[i].map(|p| {
                    let j = p.jet(tau);
                    [j[0], j[1], j[2]]
                })),
                None => aligned(jets[i][0][0], jet).ok_or_else(|| {
                    (
                        i,
                        format!(
                            "at t = {} s the horizontal speed is below {MIN_COURSE_SPEED} m/s, \
                             so the heading cannot follow the velocity: give `yaw_deg`, \
                             `pitch_deg`, `roll_deg` at every waypoint",
                            times[i] + tau
                        ),
                    )
                }),
            };
            let a = match last_att {
                Some(l) => l,
                None => att(ta, &ja)?,
            };
            let mut b = att(tb, &jb)?;
            if euler.is_none() {
                // Keep yaw continuous across ±π.
                let turns = ((b[0][0] - a[0][0]) / std::f64::consts::TAU).round();
                b[0][0] -= turns * std::f64::consts::TAU;
            }
            last_att = Some(b);
            let zero = Poly::constant(0.0);
            let e = |k: usize| Poly::hermite5(a[k], b[k], tb - ta);
            pieces.push(Piece {
                t0: times[i] + ta,
                duration: tb - ta,
                poly: std::array::from_fn::<_, CHANNELS, _>(|k| if k < 3 { e(k) } else { zero }),
                segment: i,
            });
            knots.push(Knot {
                t0: times[i] + ta,
                lat0: jets[i][0][0],
                lon0: jets[i][1][0],
                lat: fit(0),
                lon: fit(1),
                h: fit(2),
                piece: pieces.len() - 1,
            });
        }
        segments.push(Segment {
            line: wps[i].0,
            span: (times[i], times[i + 1]),
            gnss_visible: wps[i].1.gnss.unwrap_or(true),
        });
    }
    let m = DefinedMotion {
        knots,
        pieces,
        segments,
        end: times[wps.len() - 1],
    };
    let g = earth::normal_gravity(origin[0].sin(), origin[2]);
    m.check_load(g, lim.max_g, Some(lim.max_rate))?;
    Ok(m)
}

/// Times increase, values are finite, each waypoint has one kind of position, and either
/// every waypoint has an orientation or none has; returns whether they have.
fn check(wps: &[(u64, &WaypointSpec)]) -> Result<bool, Refusal> {
    let mut oriented = 0;
    for (i, (_, w)) in wps.iter().enumerate() {
        let v = w.velocity_m_s.unwrap_or([0.0; 3]);
        for (k, x) in [
            ("t_s", Some(w.t_s)),
            ("north_m", w.north_m),
            ("east_m", w.east_m),
            ("down_m", w.down_m),
            ("lat_deg", w.lat_deg),
            ("lon_deg", w.lon_deg),
            ("h_m", w.h_m),
            ("velocity_m_s", Some(v[0] + v[1] + v[2])),
            ("yaw_deg", w.yaw_deg),
            ("pitch_deg", w.pitch_deg),
            ("roll_deg", w.roll_deg),
        ] {
            if let Some(x) = x.filter(|x| !x.is_finite()) {
                return Err((i, format!("`{k}` = {x}: expected a finite number")));
            }
        }
        if w.t_s.abs() > limits::MAX_ABS_TIME_S {
            return Err((i, format!("`t_s` = {}: beyond ±1e10 s", w.t_s)));
        }
        if i > 0 && w.t_s <= wps[i - 1].1.t_s {
            return Err((
                i,
                format!(
                    "`t_s` = {} is not after the previous waypoint's {} s: times of arrival \
                     must increase",
                    w.t_s,
                    wps[i - 1].1.t_s
                ),
            ));
        }
        if v.iter().map(|x| x * x).sum::<f64>().sqrt() > limits::MAX_SPEED_M_S {
            return Err((i, "`velocity_m_s` is beyond 3e4 m/s".into()));
        }
        let ned = w.north_m.is_some() || w.east_m.is_some() || w.down_m.is_some();
        let geo = w.lat_deg.is_some() || w.lon_deg.is_some() || w.h_m.is_some();
        if ned == geo || (geo && (w.lat_deg.is_none() || w.lon_deg.is_none())) {
            return Err((
                i,
                "give the position as `north_m`/`east_m`/`down_m` (offsets from `start`) or \
                 as `lat_deg` and `lon_deg` (with `h_m`), not both"
                    .into(),
            ));
        }
        if w.lat_deg.is_some_and(|l| l.abs() > 89.0) {
            return Err((
                i,
                "`lat_deg` beyond ±89° (the heading is undefined at the poles)".into(),
            ));
        }
        if w.yaw_deg.is_some() || w.pitch_deg.is_some() || w.roll_deg.is_some() {
            oriented += 1;
        }
    }
    if oriented != 0 && oriented != wps.len() {
        let i = wps
            .iter()
            .position(|(_, w)| w.yaw_deg.or(w.pitch_deg).or(w.roll_deg).is_none())
            .unwrap_or(0);
        return Err((
            i,
            "no orientation here while other waypoints have one: give `yaw_deg`/`pitch_deg`/\
             `roll_deg` at every waypoint or at none (the heading then follows the velocity)"
                .into(),
        ));
    }
    Ok(oriented != 0)
}

/// The geodetic position (rad, rad, m) of a waypoint: NED offsets are taken in the start's
/// local frame and converted through ECEF exactly.
fn position(w: &WaypointSpec, origin: [f64; 3]) -> [f64; 3] {
    if let Some(lat) = w.lat_deg {
        let lon = near(w.lon_deg.unwrap_or(0.0).to_radians(), origin[1]);
        return [lat.to_radians(), lon, w.h_m.unwrap_or(origin[2])];
    }
    let o = Geodetic::from_radians(origin[0], origin[1], origin[2]);
    let (sp, cp, sl, cl) = (o.sin_lat, o.cos_lat, o.sin_lon, o.cos_lon);
    let [n, e, d] = [w.north_m, w.east_m, w.down_m].map(|x| x.unwrap_or(0.0));
    let r = o.to_ecef()
        + Vec3::new(-sp * cl, -sp * sl, cp) * n
        + Vec3::new(-sl, cl, 0.0) * e
        + Vec3::new(-cp * cl, -cp * sl, -sp) * d;
    let g = earth::ecef_to_geodetic(r);
    [g.lat(), near(g.lon(), origin[1]), g.h]
}

/// Longitude `lon` moved by whole turns to within π of `of`, so that the path does not go
/// round the Earth across ±180°.
fn near(lon: f64, of: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    of + (lon - of + PI).rem_euclid(TAU) - PI
}

/// First and second derivatives at the knots `t` of the natural cubic spline through `y`
/// (second derivative zero at both ends; a straight line for two knots).
pub(crate) fn natural_spline(t: &[f64], y: &[f64]) -> Vec<(f64, f64)> {
    let n = t.len();
    let h: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let slope: Vec<f64> = (0..n - 1).map(|i| (y[i + 1] - y[i]) / h[i]).collect();
    // Second derivatives m: h_{i−1} m_{i−1} + 2(h_{i−1} + h_i) m_i + h_i m_{i+1}
    // = 6 (slope_i − slope_{i−1}), m_0 = m_{n−1} = 0 (Thomas algorithm).
    let mut m = vec![0.0; n];
    if n > 2 {
        let mut diag = vec![0.0; n];
        let mut rhs = vec![0.0; n];
        for i in 1..n - 1 {
            diag[i] = 2.0 * (h[i - 1] + h[i]);
            rhs[i] = 6.0 * (slope[i] - slope[i - 1]);
            if i > 1 {
                let f = h[i - 1] / diag[i - 1];
                diag[i] -= f * h[i - 1];
                rhs[i] -= f * rhs[i - 1];
            }
        }
        for i in (1..n - 1).rev() {
            let next = if i + 1 < n - 1 { h[i] * m[i + 1] } else { 0.0 };
            m[i] = (rhs[i] - next) / diag[i];
        }
    }
    (0..n)
        .map(|i| {
            let d1 = if i + 1 < n {
                slope[i] - h[i] * (2.0 * m[i] + m[i + 1]) / 6.0
            } else {
                slope[i - 1] + h[i - 1] * (m[i - 1] + 2.0 * m[i]) / 6.0
            };
            (d1, m[i])
        })
        .collect()
}

/// Per interval, the quintics of yaw, pitch, roll through the angles given at the
/// waypoints (the natural spline's rates and second derivatives; yaw and roll unwrapped so
/// that each step turns the short way).
fn euler_jets(wps: &[(u64, &WaypointSpec)], t: &[f64]) -> Vec<[Poly; 3]> {
    let mut ch: [Vec<f64>; 3] = Default::default();
    for (_, w) in wps {
        for (k, a) in [w.yaw_deg, w.pitch_deg, w.roll_deg].into_iter().enumerate() {
            let mut a = a.unwrap_or(0.0).to_radians();
            if let Some(prev) = ch[k].last() {
                a -= std::f64::consts::TAU * ((a - prev) / std::f64::consts::TAU).round();
            }
            ch[k].push(a);
        }
    }
    let sp = ch.each_ref().map(|y| natural_spline(t, y));
    (0..t.len() - 1)
        .map(|i| {
            std::array::from_fn(|k| {
                let (a, b) = (sp[k][i], sp[k][i + 1]);
                Poly::hermite5(
                    [ch[k][i], a.0, a.1],
                    [ch[k][i + 1], b.0, b.1],
                    t[i + 1] - t[i],
                )
            })
        })
        .collect()
}

/// Value and first two derivatives of a function of time.
#[derive(Clone, Copy, Debug)]
struct J2([f64; 3]);

impl std::ops::Add for J2 {
    type Output = J2;
    fn add(self, o: J2) -> J2 {
        J2([0, 1, 2].map(|k| self.0[k] + o.0[k]))
    }
}

impl std::ops::Mul for J2 {
    type Output = J2;
    fn mul(self, o: J2) -> J2 {
        let ([a, a1, a2], [b, b1, b2]) = (self.0, o.0);
        J2([a * b, a1 * b + a * b1, a2 * b + 2.0 * a1 * b1 + a * b2])
    }
}

impl J2 {
    fn constant(c: f64) -> J2 {
        J2([c, 0.0, 0.0])
    }
    fn scale(self, c: f64) -> J2 {
        J2(self.0.map(|x| x * c))
    }
    /// f(a) with f, f′, f″ at a: the chain rule.
    fn chain(self, f: [f64; 3]) -> J2 {
        let [_, a1, a2] = self.0;
        J2([f[0], f[1] * a1, f[2] * a1 * a1 + f[1] * a2])
    }
    fn sin(self) -> J2 {
        let (s, c) = self.0[0].sin_cos();
        self.chain([s, c, -s])
    }
    fn cos(self) -> J2 {
        let (s, c) = self.0[0].sin_cos();
        self.chain([c, -s, -c])
    }
    /// a^p.
    fn powf(self, p: f64) -> J2 {
        let a = self.0[0];
        self.chain([
            a.powf(p),
            p * a.powf(p - 1.0),
            p * (p - 1.0) * a.powf(p - 2.0),
        ])
    }
    /// atan2(self, x): θ′ = (x y′ − y x′)/(x² + y²).
    fn atan2(self, x: J2) -> J2 {
        let ([y, y1, y2], [x0, x1, x2]) = (self.0, x.0);
        let (u, v) = (x0 * y1 - y * x1, x0 * x0 + y * y);
        let (u1, v1) = (x0 * y2 - y * x2, 2.0 * (x0 * x1 + y * y1));
        J2([y.atan2(x0), u / v, (u1 * v - u * v1) / (v * v)])
    }
}

/// Yaw, pitch (jets: angle, rate, second derivative) and roll 0 of a vehicle whose body x
/// axis follows the velocity, from the jets [p, p′, p″, p‴] of latitude (change from
/// `lat0`), longitude and height; `None` when the horizontal speed is too small for a
/// heading.
fn aligned(lat0: f64, p: &[Jet; 3]) -> Option<[[f64; 3]; 3]> {
    let [la, lo, h] = p;
    let lat = J2([lat0 + la[0], la[1], la[2]]);
    let lat_d = J2([la[1], la[2], la[3]]);
    let lon_d = J2([lo[1], lo[2], lo[3]]);
    let (h, h_d) = (J2([h[0], h[1], h[2]]), J2([h[1], h[2], h[3]]));
    let s = lat.sin();
    let w = (s * s).scale(-E2) + J2::constant(1.0);
    let rn = w.powf(-0.5).scale(earth::A);
    let rm = w.powf(-1.5).scale(earth::A * (1.0 - E2));
    let vn = (rm + h) * lat_d;
    let ve = (rn + h) * lat.cos() * lon_d;
    let up = h_d;
    let horiz = (vn * vn + ve * ve).powf(0.5);
    if horiz.0[0].is_nan() || horiz.0[0] < MIN_COURSE_SPEED {
        return None;
    }
    Some([ve.atan2(vn).0, up.atan2(horiz).0, [0.0; 3]])
}
