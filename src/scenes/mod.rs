//! Built-in analytic scenes: trajectories given by closed-form functions of time, evaluated
//! exactly (no sampling). Each has parameters with defaults, settable from a scene file.

pub mod fixed;
pub mod flight;
pub mod path;

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use crate::earth;
use crate::math::quat_from_euler;
use crate::motion::limits;
use crate::quadrature::GaussLegendre;
pub use fixed::{FixedScene, PolarScene};
pub use flight::{FlightPiece, FlightScene};
use path::{Jet, Planar, Poly};

/// Names of the built-in scenes, in the order `imu-emu scenes` lists them.
pub const NAMES: [&str; 6] = ["static", "straight", "circle", "survey", "coning", "polar"];

/// The default scene of the main job.
pub const DEFAULT: &str = "survey";

/// Parameters of the built-in scenes (angles in degrees, lengths in metres, SI otherwise).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SceneParams {
    /// Latitude of the place or map origin (deg).
    pub lat_deg: f64,
    /// Longitude (deg).
    pub lon_deg: f64,
    /// Ellipsoidal height (m); for `survey` the height of the survey lines.
    pub h_m: f64,
    /// Attitude of `static` and reference attitude of `coning` (deg).
    pub roll_deg: f64,
    /// Pitch (deg).
    pub pitch_deg: f64,
    /// Yaw / heading (deg); for `straight` the track direction.
    pub yaw_deg: f64,
    /// Speed (m/s) of `straight`, `circle`, `survey`, `polar`.
    pub speed_m_s: f64,
    /// Turn radius of `circle` (m).
    pub radius_m: f64,
    /// Turn direction of `circle`: true for right (clockwise seen from above).
    pub turn_right: bool,
    /// Bank of the `survey` turns (deg).
    pub bank_deg: f64,
    /// Height at the start of the `survey` climb (m).
    pub start_h_m: f64,
    /// Number of `survey` lines after the climb leg.
    pub lines: u32,
    /// Duration of each `survey` line (s).
    pub line_s: f64,
    /// Half-cone angle of `coning` (deg).
    pub cone_half_angle_deg: f64,
    /// Coning frequency (Hz).
    pub cone_hz: f64,
    /// Amplitude of an optional roll oscillation on the flight scenes (deg).
    pub roll_osc_deg: f64,
    /// Frequency of that roll oscillation (Hz).
    pub roll_osc_hz: f64,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            lat_deg: 41.0,
            lon_deg: 0.0,
            h_m: 0.0,
            roll_deg: 0.0,
            pitch_deg: 0.0,
            yaw_deg: 0.0,
            speed_m_s: 0.0,
            radius_m: 500.0,
            turn_right: true,
            bank_deg: 25.0,
            start_h_m: 300.0,
            lines: 3,
            line_s: 104.0,
            cone_half_angle_deg: 1.0,
            cone_hz: 2.0,
            roll_osc_deg: 0.0,
            roll_osc_hz: 0.0,
        }
    }
}

impl SceneParams {
    /// The defaults of one scene (which differ in place, speed and height).
    pub fn defaults_for(name: &str) -> SceneParams {
        let d = SceneParams::default();
        match name {
            "straight" => SceneParams {
                h_m: 1000.0,
                speed_m_s: 100.0,
                yaw_deg: 90.0,
                ..d
            },
            "circle" => SceneParams {
                h_m: 1000.0,
                speed_m_s: 50.0,
                ..d
            },
            // Castelldefels, where the seed paper's institute flies its survey tests.
            "survey" => SceneParams {
                lat_deg: 41.27,
                lon_deg: 1.98,
                h_m: 1000.0,
                speed_m_s: 60.0,
                ..d
            },
            "polar" => SceneParams {
                h_m: 1000.0,
                speed_m_s: 200.0,
                ..d
            },
            _ => d,
        }
    }
}

/// Heights a scene may have (m): the limits of trajectory input.
const HEIGHTS: std::ops::RangeInclusive<f64> = limits::MIN_HEIGHT_M..=limits::MAX_HEIGHT_M;
const HEIGHT_RANGE: &str = "a height in [−1e5, 1e8] m";

/// Speeds of the moving scenes (m/s): their attitude follows the track, which needs a speed
/// (0.01 m/s keeps the survey's turn rate g·tan(bank)/speed under the rate limit), and at
/// most the speed limit of trajectory input.
const SPEEDS: std::ops::RangeInclusive<f64> = 0.01..=limits::MAX_SPEED_M_S;
const SPEED_RANGE: &str = "a positive speed in [0.01, 3e4] m/s";

/// Most `survey` lines: about 100 MB of pieces, 150 days of flight at the defaults.
pub const MAX_LINES: u32 = 100_000;

/// Longest `survey` line (s).
const MAX_LINE_S: f64 = 1.0e6;

/// A scene parameter outside its valid range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("scene `{scene}`: parameter `{key}` = {}: {expected}", crate::csvio::num(*value))]
pub struct SceneParamError {
    /// Scene name.
    pub scene: String,
    /// Parameter key.
    pub key: &'static str,
    /// Offending value.
    pub value: f64,
    /// What is expected.
    pub expected: &'static str,
}

/// An unknown scene name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown scene `{0}` (built-in scenes: static, straight, circle, survey, coning, polar)")]
pub struct UnknownScene(pub String);

/// A built-in analytic scene, ready to evaluate.
#[derive(Clone, Debug)]
pub enum Scene {
    /// Static or coning.
    Fixed(FixedScene),
    /// Straight, circle, survey.
    Flight(FlightScene),
    /// Over the pole.
    Polar(PolarScene),
}

/// Builds scene `name` with parameters `p`.
pub fn build(name: &str, p: &SceneParams) -> Result<Result<Scene, SceneParamError>, UnknownScene> {
    let check = |key: &'static str, value: f64, ok: bool, expected: &'static str| {
        if ok && value.is_finite() {
            Ok(())
        } else {
            Err(SceneParamError {
                scene: name.to_string(),
                key,
                value,
                expected,
            })
        }
    };
    let r = |v: f64| v.to_radians();
    let inner = || -> Result<Scene, SceneParamError> {
        let numbers = [
            ("lat_deg", p.lat_deg),
            ("lon_deg", p.lon_deg),
            ("h_m", p.h_m),
            ("roll_deg", p.roll_deg),
            ("pitch_deg", p.pitch_deg),
            ("yaw_deg", p.yaw_deg),
            ("speed_m_s", p.speed_m_s),
            ("radius_m", p.radius_m),
            ("bank_deg", p.bank_deg),
            ("start_h_m", p.start_h_m),
            ("line_s", p.line_s),
            ("cone_half_angle_deg", p.cone_half_angle_deg),
            ("cone_hz", p.cone_hz),
            ("roll_osc_deg", p.roll_osc_deg),
            ("roll_osc_hz", p.roll_osc_hz),
        ];
        for (key, value) in numbers {
            check(key, value, true, "a finite number")?;
        }
        check(
            "lat_deg",
            p.lat_deg,
            p.lat_deg.abs() <= 90.0,
            "a latitude within ±90°",
        )?;
        check("h_m", p.h_m, HEIGHTS.contains(&p.h_m), HEIGHT_RANGE)?;
        let check_speed = || {
            check(
                "speed_m_s",
                p.speed_m_s,
                SPEEDS.contains(&p.speed_m_s),
                SPEED_RANGE,
            )
        };
        // A roll oscillation's peak rate, amplitude × 2πf, within the limit of the kinematics.
        let osc_rate = r(p.roll_osc_deg).abs() * 2.0 * PI * p.roll_osc_hz.abs();
        check(
            "roll_osc_hz",
            p.roll_osc_hz,
            osc_rate <= limits::MAX_RATE_RAD_S,
            "a frequency whose roll rate, amplitude × 2π × frequency, is at most 1e4 rad/s",
        )?;
        let roll_osc =
            (p.roll_osc_deg != 0.0).then(|| (r(p.roll_osc_deg), 2.0 * PI * p.roll_osc_hz));
        match name {
            "static" | "coning" => {
                let q = quat_from_euler(r(p.roll_deg), r(p.pitch_deg), r(p.yaw_deg));
                let coning = if name == "coning" {
                    check(
                        "cone_hz",
                        p.cone_hz,
                        p.cone_hz > 0.0 && 2.0 * PI * p.cone_hz <= limits::MAX_RATE_RAD_S,
                        "a positive frequency up to 1e4/2π ≈ 1592 Hz",
                    )?;
                    Some((r(p.cone_half_angle_deg), 2.0 * PI * p.cone_hz))
                } else {
                    None
                };
                Ok(Scene::Fixed(FixedScene::new(
                    r(p.lat_deg),
                    r(p.lon_deg),
                    p.h_m,
                    q,
                    coning,
                )))
            }
            "straight" => {
                check_speed()?;
                let (s, c) = r(p.yaw_deg).sin_cos();
                let planar = [(
                    0.0,
                    Planar::Poly(
                        Poly::linear(0.0, p.speed_m_s * c),
                        Poly::linear(0.0, p.speed_m_s * s),
                    ),
                )];
                let height = [(0.0, Poly::constant(p.h_m))];
                let pieces = FlightScene::merge(&planar, &height);
                Ok(Scene::Flight(FlightScene::new(
                    r(p.lat_deg),
                    r(p.lon_deg),
                    p.h_m,
                    pieces,
                    f64::INFINITY,
                    roll_osc,
                )))
            }
            "circle" => {
                check_speed()?;
                let v = p.speed_m_s;
                check(
                    "radius_m",
                    p.radius_m,
                    p.radius_m > 0.0
                        && v * v / p.radius_m <= limits::MAX_ACCEL_M_S2
                        && v / p.radius_m <= limits::MAX_RATE_RAD_S,
                    "a positive radius with speed²/radius ≤ 1e5 m/s² and speed/radius ≤ 1e4 rad/s",
                )?;
                let sign = if p.turn_right { 1.0 } else { -1.0 };
                let arc = Planar::Arc {
                    centre: [0.0, sign * p.radius_m],
                    radius: p.radius_m,
                    psi0: 0.0,
                    rate: sign * p.speed_m_s / p.radius_m,
                };
                let pieces = FlightScene::merge(&[(0.0, arc)], &[(0.0, Poly::constant(p.h_m))]);
                Ok(Scene::Flight(FlightScene::new(
                    r(p.lat_deg),
                    r(p.lon_deg),
                    p.h_m,
                    pieces,
                    f64::INFINITY,
                    roll_osc,
                )))
            }
            "survey" => {
                check_speed()?;
                check(
                    "bank_deg",
                    p.bank_deg,
                    p.bank_deg > 0.0 && p.bank_deg < 80.0,
                    "a bank angle in (0°, 80°)",
                )?;
                check(
                    "line_s",
                    p.line_s,
                    p.line_s > 0.0 && p.line_s <= MAX_LINE_S,
                    "a positive duration up to 1e6 s",
                )?;
                check(
                    "lines",
                    p.lines.into(),
                    p.lines <= MAX_LINES,
                    "at most 100000 lines",
                )?;
                check(
                    "start_h_m",
                    p.start_h_m,
                    HEIGHTS.contains(&p.start_h_m),
                    HEIGHT_RANGE,
                )?;
                Ok(Scene::Flight(survey(p, roll_osc)))
            }
            "polar" => {
                check_speed()?;
                let rn_pole = earth::radius_meridian(1.0) + p.h_m;
                let mu_rate = p.speed_m_s / rn_pole;
                // Start one minute before the pole.
                let mu0 = PI / 2.0 - 60.0 * mu_rate;
                Ok(Scene::Polar(PolarScene::new(
                    r(p.lon_deg),
                    p.h_m,
                    mu0,
                    mu_rate,
                )))
            }
            _ => unreachable!("name checked by the caller"),
        }
    };
    if !NAMES.contains(&name) {
        return Err(UnknownScene(name.to_string()));
    }
    Ok(inner())
}

/// Smooth step S(s) = 3s² − 2s³ (curvature ramp: continuous bank rate) and its integral.
fn ramp_integral(s: f64) -> f64 {
    s * s * s - 0.5 * s * s * s * s
}

/// Displacement over a curvature-ramp transition of duration `t`, starting at heading `psi0`,
/// with heading ψ(τ) = ψ₀ + σΩt·I(τ/t) (I = ramp_integral, or s − I(s) when ramping down).
/// `rule` is a 16-node Gauss–Legendre rule (built once per scene: building one costs as much
/// as thousands of transitions).
fn transition_end(
    rule: &GaussLegendre,
    v: f64,
    psi0: f64,
    turn: f64,
    t: f64,
    up: bool,
) -> ([f64; 2], f64) {
    let heading = |s: f64| {
        let i = if up {
            ramp_integral(s)
        } else {
            s - ramp_integral(s)
        };
        psi0 + turn * t * i
    };
    let (mut dx, mut dy) = (0.0, 0.0);
    for (x, w) in rule.nodes.iter().zip(&rule.weights) {
        let (s, c) = heading(*x).sin_cos();
        dx += w * v * t * c;
        dy += w * v * t * s;
    }
    ([dx, dy], heading(1.0))
}

/// Straight-line jets at heading ψ and speed V, at position p.
fn line_jets(p: [f64; 2], v: f64, psi: f64) -> (Jet, Jet) {
    let (s, c) = psi.sin_cos();
    ([p[0], v * c, 0.0, 0.0], [p[1], v * s, 0.0, 0.0])
}

/// Jets of uniform circular motion at heading ψ (turn rate w, signed).
fn arc_jets(p: [f64; 2], v: f64, psi: f64, w: f64) -> (Jet, Jet) {
    let (s, c) = psi.sin_cos();
    (
        [p[0], v * c, -v * w * s, -v * w * w * c],
        [p[1], v * s, v * w * c, -v * w * w * s],
    )
}

/// The aerial survey: a straight climb leg north, then `lines` parallel lines joined by 180°
/// banked turns (alternately right and left), each turn rolling in and out over 5 s with
/// continuous bank rate (degree-7 transitions matching position to jerk at both ends).
fn survey(p: &SceneParams, roll_osc: Option<(f64, f64)>) -> FlightScene {
    let v = p.speed_m_s;
    let g0 = earth::normal_gravity(p.lat_deg.to_radians().sin(), p.h_m);
    let radius = v * v / (g0 * p.bank_deg.to_radians().tan());
    let omega = v / radius;
    let t_tr = 5.0;
    let climb_leg = 150.0;
    let mut planar: Vec<(f64, Planar)> = Vec::new();
    let mut pos = [0.0, 0.0];
    let mut psi: f64 = 0.0;
    let mut t = 0.0;
    let mut leg = climb_leg;
    let rule = GaussLegendre::new(16).expect("16 nodes supported");
    for line in 0..=p.lines {
        let (s, c) = psi.sin_cos();
        planar.push((
            t,
            Planar::Poly(Poly::linear(pos[0], v * c), Poly::linear(pos[1], v * s)),
        ));
        pos = [pos[0] + v * c * leg, pos[1] + v * s * leg];
        t += leg;
        leg = p.line_s;
        if line == p.lines {
            break;
        }
        let sign = if line % 2 == 0 { 1.0 } else { -1.0 };
        let w = sign * omega;
        // Roll-in: straight → arc.
        let (d, psi_e) = transition_end(&rule, v, psi, w, t_tr, true);
        let p_e = [pos[0] + d[0], pos[1] + d[1]];
        let (sx, sy) = line_jets(pos, v, psi);
        let (ex, ey) = arc_jets(p_e, v, psi_e, w);
        planar.push((
            t,
            Planar::Poly(Poly::hermite7(sx, ex, t_tr), Poly::hermite7(sy, ey, t_tr)),
        ));
        t += t_tr;
        // Arc.
        let (sp, cp) = psi_e.sin_cos();
        let r = radius * sign;
        let centre = [p_e[0] - r * sp, p_e[1] + r * cp];
        let t_arc = (PI - omega * t_tr) / omega;
        planar.push((
            t,
            Planar::Arc {
                centre,
                radius,
                psi0: psi_e,
                rate: w,
            },
        ));
        t += t_arc;
        let psi_a = psi_e + w * t_arc;
        let (sa, ca) = psi_a.sin_cos();
        let p_a = [centre[0] + r * sa, centre[1] - r * ca];
        // Roll-out: arc → straight.
        let (d, psi_f) = transition_end(&rule, v, psi_a, w, t_tr, false);
        let p_f = [p_a[0] + d[0], p_a[1] + d[1]];
        let (sx, sy) = arc_jets(p_a, v, psi_a, w);
        let (ex, ey) = line_jets(p_f, v, psi_f);
        planar.push((
            t,
            Planar::Poly(Poly::hermite7(sx, ex, t_tr), Poly::hermite7(sy, ey, t_tr)),
        ));
        t += t_tr;
        pos = p_f;
        psi = psi_f;
    }
    // Height: level at the start height, a C³ climb over 120 s, then level.
    let (t_c0, t_c) = (10.0, 120.0);
    let dh = p.h_m - p.start_h_m;
    let mut climb = [0.0; 8];
    climb[0] = p.start_h_m;
    for (k, c) in [(4, 35.0), (5, -84.0), (6, 70.0), (7, -20.0)] {
        climb[k] = dh * c / f64::powi(t_c, k as i32);
    }
    let height = [
        (0.0, Poly::constant(p.start_h_m)),
        (t_c0, Poly::new(climb)),
        (t_c0 + t_c, Poly::constant(p.h_m)),
    ];
    let pieces = FlightScene::merge(&planar, &height);
    FlightScene::new(
        p.lat_deg.to_radians(),
        p.lon_deg.to_radians(),
        p.h_m,
        pieces,
        t,
        roll_osc,
    )
}
