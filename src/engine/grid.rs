//! A run's time grid: the span asked for, checked against the motion, as t₀, a rate and a
//! number of records; and which records a time has released.

use crate::motion::Motion;

use super::EngineError;

/// Duration of a run on an unbounded scene when none is given (s).
pub const DEFAULT_UNBOUNDED_DURATION_S: f64 = 60.0;

/// The time grid of a run: t₀ and the number of records.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// t₀ (s); record k is at t₀ + k/rate.
    pub t0: f64,
    /// IMU rate (Hz).
    pub rate_hz: f64,
    /// Number of records.
    pub count: u64,
}

/// Checks a requested span against the motion and returns the grid.
pub fn plan(
    motion: &impl Motion,
    rate_hz: f64,
    start: Option<f64>,
    duration: Option<f64>,
) -> Result<Grid, EngineError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0 && rate_hz <= 1.0e7) {
        return Err(EngineError::Setting {
            key: "rate",
            value: rate_hz.to_string(),
            expected: "a rate in (0, 1e7] Hz",
        });
    }
    let (m0, m1) = (motion.start(), motion.end());
    let t0 = start.unwrap_or(m0);
    if !t0.is_finite() {
        return Err(EngineError::Setting {
            key: "start",
            value: t0.to_string(),
            expected: "a finite time",
        });
    }
    let duration = match duration {
        Some(d) if d.is_finite() && d > 0.0 => d,
        Some(d) => {
            return Err(EngineError::Setting {
                key: "duration",
                value: d.to_string(),
                expected: "a positive duration in seconds",
            });
        }
        None if m1.is_finite() => m1 - t0,
        None => DEFAULT_UNBOUNDED_DURATION_S,
    };
    // Rounding slack: a span that ends within 1e-9 s of the last sample is still inside.
    let count = (duration * rate_hz + 1e-9).floor();
    let t_last = t0 + count / rate_hz;
    let slack = 1e-9 * m1.abs().max(1.0);
    if t0 < m0 - slack || t_last > m1 + slack || count < 1.0 {
        return Err(EngineError::Span {
            from: t0,
            to: t0 + duration,
            start: m0,
            end: m1,
        });
    }
    check_time_resolution(t0.abs().max(t_last.abs()), 1.0 / rate_hz)?;
    Ok(Grid {
        t0,
        rate_hz,
        count: count as u64,
    })
}

/// Number of records k ≥ 1 of `grid` with t_k = t₀ + k/rate at or before `t` (times computed
/// as the generator computes them, so the last released interval never passes `t`).
pub fn released(grid: &Grid, t: f64) -> u64 {
    let time = |k: u64| grid.t0 + k as f64 / grid.rate_hz;
    if t.is_nan() || t < grid.t0 {
        return 0;
    }
    // Past 2⁵³ records the time of record k no longer moves with k: every record is in.
    const HUGE: f64 = 9.0e15;
    let guess = ((t - grid.t0) * grid.rate_hz).floor();
    if guess >= HUGE {
        return HUGE as u64;
    }
    let mut k = guess as u64;
    while time(k + 1) <= t {
        k += 1;
    }
    while k > 0 && time(k) > t {
        k -= 1;
    }
    k
}

/// Largest spacing of representable times near a run's times, as a fraction of the record
/// interval. A time tag t₀ + k/rate is rounded to the nearest f64, off by up to half that
/// spacing, so successive tags differ from Δt by up to one spacing: at 1/1000 of Δt the tags
/// keep Δt to 0.1 % (t₀ = 1.4e9 s, a Unix time, allows rates up to about 4 kHz).
pub const TIME_RESOLUTION: f64 = 1.0e-3;

/// Refuses a run whose largest |time| `t` is held more coarsely than [`TIME_RESOLUTION`]·`dt`.
fn check_time_resolution(t: f64, dt: f64) -> Result<(), EngineError> {
    // Spacing of f64 values at t: the next representable value above |t|, minus |t|.
    let ulp = f64::from_bits(t.to_bits() + 1) - t;
    if ulp > TIME_RESOLUTION * dt {
        return Err(EngineError::TimeResolution { t, ulp, dt });
    }
    Ok(())
}
