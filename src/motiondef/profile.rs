//! A prescribed motion: the ZYX Euler angles (yaw, pitch, roll) and the body-frame velocity as
//! piecewise polynomials of time, built command by command. Every join matches value, first
//! and second derivative (quintic Hermite blends), so the angular rate, the angular
//! acceleration and the specific force never jump.

use crate::scenes::path::Poly;

/// The channels, in the order of gnss-ins-sim's command columns: yaw, pitch, roll (rad) and
/// the body velocity x, y, z (m/s).
pub const CHANNELS: usize = 6;

/// Duration over which a change of commanded rate is blended in (s): long enough that a
/// 10°/s rate step asks for under 1 rad/s² of angular acceleration.
pub const BLEND_S: f64 = 0.5;

/// One polynomial piece of the prescribed motion.
#[derive(Clone, Debug)]
pub struct Piece {
    /// Start time (s); the polynomials are in τ = t − t0.
    pub t0: f64,
    /// Duration (s).
    pub duration: f64,
    /// yaw, pitch, roll (rad), v_x, v_y, v_z body (m/s).
    pub poly: [Poly; CHANNELS],
    /// Index of the command (segment) that made this piece.
    pub segment: usize,
}

/// The manoeuvre limits of the targeted commands (gnss-ins-sim's "mobility").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mobility {
    /// Largest body acceleration per axis (m/s²).
    pub max_accel: f64,
    /// Largest Euler-angle acceleration per axis (rad/s²).
    pub max_angular_accel: f64,
    /// Largest Euler-angle rate per axis (rad/s).
    pub max_rate: f64,
}

/// Builds the pieces one command at a time from the state at the end of the previous one.
#[derive(Clone, Debug)]
pub struct Profile {
    pieces: Vec<Piece>,
    t: f64,
    /// Value, first and second derivative of each channel at `t`.
    state: [[f64; 3]; CHANNELS],
    segment: usize,
}

impl Profile {
    /// Starts at rest in every rate, with `initial` values, at time `t0`.
    pub fn new(t0: f64, initial: [f64; CHANNELS]) -> Profile {
        Profile {
            pieces: Vec::new(),
            t: t0,
            state: initial.map(|v| [v, 0.0, 0.0]),
            segment: 0,
        }
    }

    /// The index the next pieces are tagged with.
    pub fn set_segment(&mut self, segment: usize) {
        self.segment = segment;
    }

    /// Current values of the channels.
    pub fn values(&self) -> [f64; CHANNELS] {
        self.state.map(|s| s[0])
    }

    /// Current time (s).
    pub fn time(&self) -> f64 {
        self.t
    }

    /// The pieces built so far.
    pub fn pieces(&self) -> &[Piece] {
        &self.pieces
    }

    /// Holds every channel's rate at `rates` (Euler-angle rates in rad/s, body accelerations
    /// in m/s²) for `duration`, the change of rate blended over the first
    /// min([`BLEND_S`], duration) seconds (the blend ends at half the sum of the old and new
    /// rates times its length, so the rate profile is symmetric about its mid-point).
    pub fn rates(&mut self, rates: [f64; CHANNELS], duration: f64) {
        let tb = BLEND_S.min(duration);
        if tb <= 0.0 {
            return;
        }
        let blend: [Poly; CHANNELS] = std::array::from_fn(|k| {
            let [v, d1, d2] = self.state[k];
            Poly::hermite5(
                [v, d1, d2],
                [v + 0.5 * (d1 + rates[k]) * tb, rates[k], 0.0],
                tb,
            )
        });
        self.push(blend, tb);
        let rest = duration - tb;
        if rest > 0.0 {
            let line = std::array::from_fn(|k| Poly::linear(self.state[k][0], rates[k]));
            self.push(line, rest);
        }
    }

    /// Blends every channel from its current value, rate and acceleration to `end` (value,
    /// rate, acceleration per channel) over `duration`.
    pub fn blend_to(&mut self, end: [[f64; 3]; CHANNELS], duration: f64) {
        let poly = std::array::from_fn(|k| Poly::hermite5(self.state[k], end[k], duration));
        self.push(poly, duration);
    }

    /// Moves every channel to `target` and brings its rates to zero, in the shortest time
    /// within `limits` (angles 0..3, velocities 3..6), but stops after `max_duration` like a
    /// command that runs out of time. Returns the time taken (0 when already there at rest).
    pub fn reach(&mut self, target: [f64; CHANNELS], limits: &Mobility, max_duration: f64) -> f64 {
        let at_rest = self.state.iter().zip(target).all(|(s, g)| {
            (s[0] - g).abs() <= 1e-12 * g.abs().max(1.0) && s[1] == 0.0 && s[2] == 0.0
        });
        if at_rest || max_duration <= 0.0 {
            return 0.0;
        }
        // The minimum-jerk step 10s³ − 15s⁴ + 6s⁵ over T peaks at rate 1.875Δ/T and
        // acceleration 10Δ/(√3·T²) ≈ 5.7735Δ/T²: the least T for rest-to-rest moves, grown
        // below when the starting rates need longer.
        let mut t = BLEND_S;
        for (k, (s, g)) in self.state.iter().zip(target).enumerate() {
            let d = (g - s[0]).abs();
            t = t.max(if k < 3 {
                (1.875 * d / limits.max_rate).max((5.7735 * d / limits.max_angular_accel).sqrt())
            } else {
                1.875 * d / limits.max_accel
            });
        }
        let mut polys = self.reach_polys(target, t);
        for _ in 0..100 {
            if self.within(&polys, t, limits) {
                break;
            }
            t *= 1.1;
            polys = self.reach_polys(target, t);
        }
        let used = t.min(max_duration);
        self.push(polys, used);
        used
    }

    fn reach_polys(&self, target: [f64; CHANNELS], t: f64) -> [Poly; CHANNELS] {
        std::array::from_fn(|k| Poly::hermite5(self.state[k], [target[k], 0.0, 0.0], t))
    }

    /// Whether the blend respects the limits, each one relaxed to the starting value when
    /// that is already beyond it (a rate held by an earlier command). Sampled at 65 points:
    /// the rate is a quartic and the acceleration a cubic, whose extrema 65 points resolve
    /// to well under 1 %.
    fn within(&self, polys: &[Poly; CHANNELS], t: f64, limits: &Mobility) -> bool {
        let tol = 1.0 + 1e-9;
        (0..CHANNELS).all(|k| {
            let [_, d1, d2] = self.state[k];
            // (derivative, its limit) pairs: rate and angular acceleration of an angle, the
            // acceleration of a velocity.
            let checks: &[(usize, f64)] = if k < 3 {
                &[
                    (1, limits.max_rate.max(d1.abs())),
                    (2, limits.max_angular_accel.max(d2.abs())),
                ]
            } else {
                &[(1, limits.max_accel.max(d1.abs()))]
            };
            (0..=64).all(|i| {
                let j = polys[k].jet(t * i as f64 / 64.0);
                checks.iter().all(|&(d, lim)| j[d].abs() <= lim * tol)
            })
        })
    }

    fn push(&mut self, poly: [Poly; CHANNELS], duration: f64) {
        for (k, p) in poly.iter().enumerate() {
            let j = p.jet(duration);
            self.state[k] = [j[0], j[1], j[2]];
        }
        self.pieces.push(Piece {
            t0: self.t,
            duration,
            poly,
            segment: self.segment,
        });
        self.t += duration;
    }

    /// The finished pieces.
    pub fn into_pieces(self) -> Vec<Piece> {
        self.pieces
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Mobility = Mobility {
        max_accel: 1.0,
        max_angular_accel: 0.5,
        max_rate: 2.0,
    };

    /// Value and derivatives of channel k at the end of piece i and at the start of i + 1.
    fn join(p: &[Piece], i: usize, k: usize) -> ([f64; 4], [f64; 4]) {
        (p[i].poly[k].jet(p[i].duration), p[i + 1].poly[k].jet(0.0))
    }

    #[test]
    fn a_rate_command_turns_by_rate_times_duration_less_half_the_blend() {
        let mut pr = Profile::new(0.0, [0.0, 0.0, 0.0, 10.0, 0.0, 0.0]);
        let r = -15f64.to_radians();
        pr.rates([r, 0.0, 0.0, 0.0, 0.0, 0.0], 6.0);
        pr.rates([0.0; 6], 3.0);
        // Blending in loses r·T_b/2, blending out gains it back: −90° exactly.
        let yaw = pr.values()[0];
        assert!((yaw - 6.0 * r).abs() < 1e-14, "{}", yaw.to_degrees());
        let p = pr.pieces();
        assert_eq!(p.len(), 4);
        for i in 0..3 {
            let (a, b) = join(p, i, 0);
            for d in 0..3 {
                assert!((a[d] - b[d]).abs() < 1e-13, "join {i} d{d}: {a:?} {b:?}");
            }
        }
        // Mid-turn the rate is the commanded one.
        assert!((p[1].poly[0].jet(1.0)[1] - r).abs() < 1e-15);
    }

    #[test]
    fn a_target_command_respects_the_limits_and_arrives_at_rest() {
        let mut pr = Profile::new(0.0, [0.0; 6]);
        let used = pr.reach(
            [90f64.to_radians(), 0.0, 0.0, 10.0, 0.0, 0.0],
            &LIMITS,
            100.0,
        );
        // Velocity sets the time: 1.875·10 m/s / 1 m/s² = 18.75 s.
        assert!((used - 18.75).abs() < 1e-12, "{used}");
        let p = &pr.pieces()[0];
        let end = p.poly[3].jet(used);
        assert!((end[0] - 10.0).abs() < 1e-12 && end[1].abs() < 1e-12);
        let peak = (0..=1000)
            .map(|i| p.poly[3].jet(used * i as f64 / 1000.0)[1])
            .fold(0.0f64, f64::max);
        assert!(peak <= 1.0 + 1e-9 && peak > 0.999, "{peak}");
    }

    #[test]
    fn a_target_command_cut_short_stops_where_it_is() {
        let mut pr = Profile::new(0.0, [0.0; 6]);
        let used = pr.reach([0.0, 0.0, 0.0, 10.0, 0.0, 0.0], &LIMITS, 5.0);
        assert_eq!(used, 5.0);
        assert!(pr.values()[3] > 0.0 && pr.values()[3] < 10.0);
    }
}
