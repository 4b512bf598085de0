//! The native motion definition: a `[motion]` table in TOML (its own file or a scene file).
//!
//! ```toml
//! [motion]
//! start = { lat_deg = 41.27, lon_deg = 1.98, h_m = 300, speed_m_s = 60 }
//! segments = [{ hold_s = 10 }, { turn_deg = 90, bank_deg = 20 }, { climb_to_m = 500, rate_m_s = 5 }]
//! ```
//!
//! Every segment starts and ends with all rates at rest; turns are coordinated (bank
//! atan(V·ψ̇/g)); the limits of `[motion.limits]` are checked and a violation names the
//! segment and its line.

use std::path::Path;

use serde::Deserialize;

use super::profile::{BLEND_S, CHANNELS, Mobility, Profile};
use super::waypoints::{self, PathLimits, WaypointSpec};
use super::{DefinedMotion, Segment, prescribed};
use crate::csvio::{FileError, num};
use crate::earth;
use crate::motion::limits;
use crate::quadrature::GaussLegendre;

/// `[motion.start]`: where and how the trip begins.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Start {
    lat_deg: f64,
    lon_deg: f64,
    h_m: f64,
    speed_m_s: f64,
    yaw_deg: f64,
    pitch_deg: f64,
    roll_deg: f64,
}

/// `[motion.limits]`: what the vehicle can do.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct Limits {
    max_bank_deg: f64,
    max_g: f64,
    max_rate_deg_s: f64,
    max_angular_accel_deg_s2: f64,
    max_accel_m_s2: f64,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_bank_deg: 60.0,
            max_g: 4.0,
            max_rate_deg_s: 60.0,
            max_angular_accel_deg_s2: 60.0,
            max_accel_m_s2: 5.0,
        }
    }
}

/// One segment: exactly one of the kind keys, with its options.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct SegmentSpec {
    hold_s: Option<f64>,
    accelerate_to_m_s: Option<f64>,
    accel_m_s2: Option<f64>,
    turn_deg: Option<f64>,
    figure_eight: Option<bool>,
    rate_deg_s: Option<f64>,
    bank_deg: Option<f64>,
    climb_to_m: Option<f64>,
    rate_m_s: Option<f64>,
    roll_deg: Option<f64>,
    pitch_deg: Option<f64>,
    yaw_deg: Option<f64>,
    duration_s: Option<f64>,
    gnss: Option<bool>,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MotionSpec {
    #[serde(default)]
    start: Start,
    #[serde(default)]
    limits: Limits,
    #[serde(default)]
    segments: Vec<toml::Spanned<SegmentSpec>>,
    waypoints: Option<Vec<toml::Spanned<WaypointSpec>>>,
    /// A gnss-ins-sim file (relative to this one) read with `gnss_ins_sim_limits`.
    gnss_ins_sim: Option<String>,
    #[serde(default)]
    gnss_ins_sim_limits: GnssInsSimLimits,
}

/// `[motion.gnss_ins_sim_limits]`: the limits of gnss-ins-sim's types 2–5 (defaults: its
/// path-generation example's 1 m/s², 0.5 rad/s², 2 rad/s).
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields, default)]
struct GnssInsSimLimits {
    max_accel_m_s2: f64,
    max_angular_accel_deg_s2: f64,
    max_rate_deg_s: f64,
}

impl Default for GnssInsSimLimits {
    fn default() -> GnssInsSimLimits {
        let m = super::gnss_ins_sim::MOBILITY;
        GnssInsSimLimits {
            max_accel_m_s2: m.max_accel,
            max_angular_accel_deg_s2: m.max_angular_accel.to_degrees(),
            max_rate_deg_s: m.max_rate.to_degrees(),
        }
    }
}

/// The document: only `[motion]` is read, so a scene file's other tables pass.
#[derive(Deserialize)]
struct Document {
    motion: Option<MotionSpec>,
}

/// 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> u64 {
    text[..offset.min(text.len())].matches('\n').count() as u64 + 1
}

/// Whether a TOML text has a `[motion]` table (a scene file with an embedded definition).
pub fn has_motion(text: &str) -> bool {
    toml::from_str::<toml::Table>(text).is_ok_and(|t| t.contains_key("motion"))
}

/// Reads the `[motion]` table of a TOML file.
pub fn read(path: &Path) -> Result<DefinedMotion, FileError> {
    let text = crate::csvio::read_text(path).map_err(|e| FileError::io(path, e))?;
    parse(&text, path)
}

/// Parses the `[motion]` table of `text`; `path` names it in messages.
pub fn parse(text: &str, path: &Path) -> Result<DefinedMotion, FileError> {
    let doc: Document = toml::from_str(text).map_err(|e| {
        let line = e.span().map_or(1, |s| line_of(text, s.start));
        FileError::line(path, line, e.message().trim().to_string())
    })?;
    let Some(spec) = doc.motion else {
        return Err(FileError::file(
            path,
            "no `[motion]` table (a native motion definition: `[motion]` with `start` and \
             `segments`; see docs/motion-definitions.md)",
        ));
    };
    if let Some(file) = &spec.gnss_ins_sim {
        return gnss_ins_sim_file(&spec, file, path);
    }
    let builder = Builder::new(&spec, path)?;
    match &spec.waypoints {
        Some(wps) => waypoint_path(&spec, &builder, wps, text, path),
        None => builder.run(&spec, text, path),
    }
}

/// A gnss-ins-sim file named by `motion.gnss_ins_sim`, read with the limits given.
fn gnss_ins_sim_file(
    spec: &MotionSpec,
    file: &str,
    path: &Path,
) -> Result<DefinedMotion, FileError> {
    if !spec.segments.is_empty() || spec.waypoints.is_some() {
        return Err(FileError::file(
            path,
            "`motion`: give one of `segments`, `waypoints` or `gnss_ins_sim`",
        ));
    }
    let l = &spec.gnss_ins_sim_limits;
    let given = [
        ("max_accel_m_s2", l.max_accel_m_s2, limits::MAX_ACCEL_M_S2),
        (
            "max_angular_accel_deg_s2",
            l.max_angular_accel_deg_s2,
            5.7e7,
        ),
        ("max_rate_deg_s", l.max_rate_deg_s, 5.7e5),
    ];
    for (k, v, top) in given {
        if !(v > 0.0 && v <= top) {
            return Err(FileError::file(
                path,
                format!(
                    "`motion.gnss_ins_sim_limits.{k}` = {}: a positive number within the \
                     kinematics' limits",
                    num(v)
                ),
            ));
        }
    }
    let mobility = Mobility {
        max_accel: l.max_accel_m_s2,
        max_angular_accel: l.max_angular_accel_deg_s2.to_radians(),
        max_rate: l.max_rate_deg_s.to_radians(),
    };
    let csv = path.parent().unwrap_or(Path::new("")).join(file);
    super::gnss_ins_sim::read_with(&csv, &mobility)
}

/// The path through `motion.waypoints`.
fn waypoint_path(
    spec: &MotionSpec,
    b: &Builder,
    wps: &[toml::Spanned<WaypointSpec>],
    text: &str,
    path: &Path,
) -> Result<DefinedMotion, FileError> {
    let s = &spec.start;
    if !spec.segments.is_empty() {
        return Err(FileError::file(
            path,
            "`motion`: give `segments` or `waypoints`, not both",
        ));
    }
    for (k, v) in [
        ("speed_m_s", s.speed_m_s),
        ("yaw_deg", s.yaw_deg),
        ("pitch_deg", s.pitch_deg),
        ("roll_deg", s.roll_deg),
    ] {
        if v != 0.0 {
            return Err(FileError::file(
                path,
                format!(
                    "`motion.start.{k}`: with waypoints the velocity and attitude come from the                      waypoints; `start` gives only the origin (`lat_deg`, `lon_deg`, `h_m`)"
                ),
            ));
        }
    }
    let list: Vec<(u64, &WaypointSpec)> = wps
        .iter()
        .map(|w| (line_of(text, w.span().start), w.get_ref()))
        .collect();
    let lim = PathLimits {
        max_g: b.max_g,
        max_rate: b.mobility.max_rate,
    };
    waypoints::build(&list, b.origin, &lim).map_err(|(i, m)| {
        let line = list.get(i).map_or(1, |w| w.0);
        FileError::line(path, line, format!("`motion.waypoints[{i}]`: {m}"))
    })
}

/// The limits in SI units, and the vehicle's state the segments need.
struct Builder {
    profile: Profile,
    mobility: Mobility,
    max_bank: f64,
    max_g: f64,
    /// The limits as written, for messages.
    given: Limits,
    g: f64,
    h: f64,
    origin: [f64; 3],
    rule: GaussLegendre,
}

/// A segment's failure: its message, for [`Builder::run`] to place.
type Refusal = String;

impl Builder {
    fn new(spec: &MotionSpec, path: &Path) -> Result<Builder, FileError> {
        let s = &spec.start;
        let l = &spec.limits;
        let bad = |key: &str, v: f64, expect: &str| {
            FileError::file(path, format!("`motion.{key}` = {}: {expect}", num(v)))
        };
        let fields = [
            ("start.lat_deg", s.lat_deg),
            ("start.lon_deg", s.lon_deg),
            ("start.h_m", s.h_m),
            ("start.speed_m_s", s.speed_m_s),
            ("start.yaw_deg", s.yaw_deg),
            ("start.pitch_deg", s.pitch_deg),
            ("start.roll_deg", s.roll_deg),
        ];
        for (k, v) in fields {
            if !v.is_finite() {
                return Err(bad(k, v, "a finite number"));
            }
        }
        if s.lat_deg.abs() > 90.0 {
            return Err(bad("start.lat_deg", s.lat_deg, "a latitude within ±90°"));
        }
        if !(limits::MIN_HEIGHT_M..=limits::MAX_HEIGHT_M).contains(&s.h_m) {
            return Err(bad("start.h_m", s.h_m, "a height in [−1e5, 1e8] m"));
        }
        if !(0.0..=limits::MAX_SPEED_M_S).contains(&s.speed_m_s) {
            return Err(bad(
                "start.speed_m_s",
                s.speed_m_s,
                "a speed in [0, 3e4] m/s",
            ));
        }
        let positive = [
            ("limits.max_bank_deg", l.max_bank_deg, 89.0),
            ("limits.max_g", l.max_g, 1e4),
            ("limits.max_rate_deg_s", l.max_rate_deg_s, 5.7e5),
            (
                "limits.max_angular_accel_deg_s2",
                l.max_angular_accel_deg_s2,
                5.7e7,
            ),
            (
                "limits.max_accel_m_s2",
                l.max_accel_m_s2,
                limits::MAX_ACCEL_M_S2,
            ),
        ];
        for (k, v, top) in positive {
            if !(v > 0.0 && v <= top) {
                return Err(bad(k, v, "a positive number within the kinematics' limits"));
            }
        }
        let r = f64::to_radians;
        let sin_lat = r(s.lat_deg).sin();
        Ok(Builder {
            profile: Profile::new(
                0.0,
                [
                    r(s.yaw_deg),
                    r(s.pitch_deg),
                    r(s.roll_deg),
                    s.speed_m_s,
                    0.0,
                    0.0,
                ],
            ),
            mobility: Mobility {
                max_accel: l.max_accel_m_s2,
                max_angular_accel: r(l.max_angular_accel_deg_s2),
                max_rate: r(l.max_rate_deg_s),
            },
            max_bank: r(l.max_bank_deg),
            max_g: l.max_g,
            given: l.clone(),
            g: earth::normal_gravity(sin_lat, s.h_m),
            h: s.h_m,
            origin: [r(s.lat_deg), r(s.lon_deg), s.h_m],
            rule: GaussLegendre::new(16).expect("16 nodes supported"),
        })
    }

    fn run(
        mut self,
        spec: &MotionSpec,
        text: &str,
        path: &Path,
    ) -> Result<DefinedMotion, FileError> {
        let mut segments = Vec::new();
        for (i, seg) in spec.segments.iter().enumerate() {
            let line = line_of(text, seg.span().start);
            let t0 = self.profile.time();
            self.profile.set_segment(i);
            let first = self.profile.pieces().len();
            self.segment(seg.get_ref())
                .map_err(|m| FileError::line(path, line, format!("`motion.segments[{i}]`: {m}")))?;
            self.h += self.climbed(first);
            segments.push(Segment {
                line,
                span: (t0, self.profile.time()),
                gnss_visible: seg.get_ref().gnss.unwrap_or(true),
            });
        }
        if self.profile.pieces().is_empty() {
            return Err(FileError::file(
                path,
                "`motion.segments`: no segment takes any time",
            ));
        }
        let m = DefinedMotion::new(self.origin, self.profile.into_pieces(), segments);
        // The closed-form checks of each segment bound its steady part; this also covers the
        // transitions (turn entry and exit, pitch-in, acceleration on top of gravity).
        m.check_load(self.g, self.max_g, None).map_err(|(i, msg)| {
            let line = m.segments().get(i).map_or(1, |s| s.line);
            FileError::line(path, line, format!("`motion.segments[{i}]`: {msg}"))
        })?;
        Ok(m)
    }

    /// Height gained over the pieces from `first` on: ∫ −v_D dt by 16-point Gauss–Legendre on
    /// ≤ 1 s sub-intervals (the integrand is smooth there: exact to round-off).
    fn climbed(&self, first: usize) -> f64 {
        let mut dh = 0.0;
        for p in &self.profile.pieces()[first..] {
            let n = p.duration.ceil().max(1.0);
            let step = p.duration / n;
            for j in 0..n as usize {
                for (x, w) in self.rule.nodes.iter().zip(&self.rule.weights) {
                    let tau = (j as f64 + x) * step;
                    dh -= w * step * prescribed(p, tau).0[2];
                }
            }
        }
        dh
    }

    fn segment(&mut self, s: &SegmentSpec) -> Result<(), Refusal> {
        let kinds = [
            s.hold_s.is_some(),
            s.accelerate_to_m_s.is_some(),
            s.turn_deg.is_some(),
            s.figure_eight.is_some(),
            s.climb_to_m.is_some(),
            s.roll_deg.is_some() || s.pitch_deg.is_some() || s.yaw_deg.is_some(),
        ];
        if kinds.iter().filter(|k| **k).count() != 1 {
            return Err(
                "give exactly one of `hold_s`, `accelerate_to_m_s`, `turn_deg`, \
                        `figure_eight`, `climb_to_m`, or an attitude manoeuvre (`roll_deg`, \
                        `pitch_deg`, `yaw_deg` with `duration_s`)"
                    .into(),
            );
        }
        for (k, v) in [
            ("hold_s", s.hold_s),
            ("accelerate_to_m_s", s.accelerate_to_m_s),
            ("accel_m_s2", s.accel_m_s2),
            ("turn_deg", s.turn_deg),
            ("rate_deg_s", s.rate_deg_s),
            ("bank_deg", s.bank_deg),
            ("climb_to_m", s.climb_to_m),
            ("rate_m_s", s.rate_m_s),
            ("roll_deg", s.roll_deg),
            ("pitch_deg", s.pitch_deg),
            ("yaw_deg", s.yaw_deg),
            ("duration_s", s.duration_s),
        ] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(format!("`{k}` = {}: expected a finite number", num(v)));
            }
        }
        if let Some(t) = s.hold_s {
            if !(t > 0.0 && t <= 1e6) {
                return Err(format!("`hold_s` = {}: expected (0, 1e6] s", num(t)));
            }
            self.profile.rates([0.0; CHANNELS], t);
        } else if let Some(v) = s.accelerate_to_m_s {
            self.accelerate(v, s.accel_m_s2)?;
        } else if let Some(a) = s.turn_deg {
            self.turn(a.to_radians(), s)?;
        } else if s.figure_eight.is_some() {
            let full = std::f64::consts::TAU;
            self.turn(full, s)?;
            self.turn(-full, s)?;
        } else if let Some(h) = s.climb_to_m {
            self.climb(h, s.rate_m_s)?;
        } else {
            self.manoeuvre(s)?;
        }
        Ok(())
    }

    fn speed(&self) -> f64 {
        self.profile.values()[3]
    }

    fn accelerate(&mut self, v: f64, accel: Option<f64>) -> Result<(), Refusal> {
        if !(0.0..=limits::MAX_SPEED_M_S).contains(&v) {
            return Err(format!(
                "`accelerate_to_m_s` = {}: expected [0, 3e4] m/s",
                num(v)
            ));
        }
        let a = accel.unwrap_or(self.mobility.max_accel);
        if !(a > 0.0 && a <= self.mobility.max_accel && a <= self.max_g * self.g) {
            return Err(format!(
                "`accel_m_s2` = {}: expected a positive acceleration up to max_accel_m_s2 = {} \
                 and max_g",
                num(a),
                num(self.mobility.max_accel)
            ));
        }
        let mut target = self.profile.values();
        target[3] = v;
        let m = Mobility {
            max_accel: a,
            ..self.mobility
        };
        self.profile.reach(target, &m, f64::INFINITY);
        Ok(())
    }

    /// Least duration of a rest-to-rest quintic move by `d` within the rate and angular
    /// acceleration limits (peaks 1.875d/T and 5.7735d/T²).
    fn move_time(&self, d: f64) -> f64 {
        let d = d.abs();
        (1.875 * d / self.mobility.max_rate)
            .max((5.7735 * d / self.mobility.max_angular_accel).sqrt())
            .max(BLEND_S)
    }

    /// A coordinated turn by `angle` (positive right): roll in while the yaw rate ramps up,
    /// hold, roll out; the yaw gained in the ramps is half their length times the rate, so the
    /// held part is angle/rate − T_in and the whole turn is exactly `angle`.
    fn turn(&mut self, angle: f64, s: &SegmentSpec) -> Result<(), Refusal> {
        let v = self.speed();
        if v <= 0.0 {
            return Err("a turn needs forward speed (accelerate first)".into());
        }
        let sign = angle.signum();
        let (rate, bank) = match (s.rate_deg_s, s.bank_deg) {
            (Some(r), None) if r > 0.0 => {
                let r = r.to_radians() * sign;
                (r, (v * r / self.g).atan())
            }
            (None, Some(b)) if b > 0.0 && b < 90.0 => {
                let b = b.to_radians() * sign;
                (self.g * b.tan() / v, b)
            }
            _ => {
                return Err(
                    "a turn needs one of `rate_deg_s` (positive) or `bank_deg` (in (0°, 90°))"
                        .into(),
                );
            }
        };
        if bank.abs() > self.max_bank {
            return Err(format!(
                "bank {}° is beyond max_bank_deg = {}°",
                num(bank.abs().to_degrees()),
                num(self.given.max_bank_deg)
            ));
        }
        if 1.0 / bank.cos() > self.max_g {
            return Err(format!(
                "load factor {} g is beyond max_g = {}",
                num(1.0 / bank.cos()),
                num(self.max_g)
            ));
        }
        if rate.abs() > self.mobility.max_rate {
            return Err(format!(
                "turn rate {}°/s is beyond max_rate_deg_s = {}",
                num(rate.abs().to_degrees()),
                num(self.given.max_rate_deg_s)
            ));
        }
        let t_in = self
            .move_time(bank)
            .max(1.875 * rate.abs() / self.mobility.max_angular_accel);
        let hold = angle.abs() / rate.abs() - t_in;
        if hold < 0.0 {
            return Err(format!(
                "a {}° turn is shorter than its roll-in and roll-out ({} s each at {}°/s): \
                 turn further or more slowly",
                num(angle.abs().to_degrees()),
                num(t_in),
                num(rate.abs().to_degrees())
            ));
        }
        let now = self.profile.values();
        // Bank from wings level, the nearest whole turn of roll (a 360° roll leaves 2π).
        let level = std::f64::consts::TAU * (now[2] / std::f64::consts::TAU).round();
        let mut end = now.map(|v| [v, 0.0, 0.0]);
        end[0] = [now[0] + 0.5 * rate * t_in, rate, 0.0];
        end[2] = [level + bank, 0.0, 0.0];
        self.profile.blend_to(end, t_in);
        let mut rates = [0.0; CHANNELS];
        rates[0] = rate;
        if hold > 0.0 {
            self.profile.rates(rates, hold);
        }
        let now = self.profile.values();
        let mut end = now.map(|v| [v, 0.0, 0.0]);
        end[0] = [now[0] + 0.5 * rate * t_in, 0.0, 0.0];
        end[2] = [level, 0.0, 0.0];
        self.profile.blend_to(end, t_in);
        Ok(())
    }

    /// Climb or descend to height `to` at vertical rate `rate`: pitch to the flight-path angle
    /// asin(rate/V), hold, pitch back; the ramps' height, ∫V sin θ dt, is found by quadrature
    /// and the held part made to end exactly at `to`.
    fn climb(&mut self, to: f64, rate: Option<f64>) -> Result<(), Refusal> {
        let v = self.speed();
        let Some(w) = rate.filter(|w| *w > 0.0 && *w < v) else {
            return Err(format!(
                "a climb needs `rate_m_s`, a positive vertical rate below the speed ({} m/s)",
                num(v)
            ));
        };
        if !(limits::MIN_HEIGHT_M..=limits::MAX_HEIGHT_M).contains(&to) {
            return Err(format!(
                "`climb_to_m` = {}: expected [−1e5, 1e8] m",
                num(to)
            ));
        }
        let dh = to - self.h;
        let gamma = (w / v).asin() * dh.signum();
        let t_p = self.move_time(gamma);
        let now = self.profile.values();
        let mut end = now.map(|v| [v, 0.0, 0.0]);
        end[1] = [gamma, 0.0, 0.0];
        let first = self.profile.pieces().len();
        self.profile.blend_to(end, t_p);
        let ramp = self.climbed(first);
        let hold = (dh.abs() - 2.0 * ramp.abs()) / w;
        if hold < 0.0 {
            return Err(format!(
                "a {} m height change is less than the pitch-in and pitch-out give ({} m) at \
                 {} m/s: climb further or more slowly",
                num(dh.abs()),
                num(2.0 * ramp.abs()),
                num(w)
            ));
        }
        if hold > 0.0 {
            self.profile.rates([0.0; CHANNELS], hold);
        }
        let now = self.profile.values();
        let mut end = now.map(|v| [v, 0.0, 0.0]);
        end[1] = [0.0, 0.0, 0.0];
        self.profile.blend_to(end, t_p);
        Ok(())
    }

    /// A roll, pitch or yaw manoeuvre: the angle changes by the given amount over
    /// `duration_s`, rest to rest, on a minimum-jerk profile.
    fn manoeuvre(&mut self, s: &SegmentSpec) -> Result<(), Refusal> {
        let Some(t) = s.duration_s.filter(|t| *t > 0.0 && *t <= 1e6) else {
            return Err("an attitude manoeuvre needs `duration_s` in (0, 1e6] s".into());
        };
        let mut delta = [0.0; 3];
        for (k, v) in [s.yaw_deg, s.pitch_deg, s.roll_deg].into_iter().enumerate() {
            delta[k] = v.unwrap_or(0.0).to_radians();
        }
        for (k, d) in delta.iter().enumerate() {
            let (rate, acc) = (1.875 * d.abs() / t, 5.7735 * d.abs() / (t * t));
            if rate > self.mobility.max_rate * (1.0 + 1e-12)
                || acc > self.mobility.max_angular_accel * (1.0 + 1e-12)
            {
                return Err(format!(
                    "{} {}° in {} s peaks at {}°/s and {}°/s², beyond max_rate_deg_s or \
                     max_angular_accel_deg_s2",
                    ["yaw", "pitch", "roll"][k],
                    num(d.to_degrees()),
                    num(t),
                    num(rate.to_degrees()),
                    num(acc.to_degrees())
                ));
            }
        }
        let now = self.profile.values();
        let mut end = now.map(|v| [v, 0.0, 0.0]);
        for k in 0..3 {
            end[k][0] += delta[k];
        }
        self.profile.blend_to(end, t);
        Ok(())
    }
}
