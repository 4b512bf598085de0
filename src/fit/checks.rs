//! What `fit` refuses before it fits anything, each with a message that says where and why:
//! a record too short for the terms it would report, time steps that are not uniform, and a
//! record that is not static. Pure: the caller names the file.

use crate::analysis::analyzer::{Analysis, CHANNELS};
use crate::units::G0;

/// Fewest octaves of Allan deviation from Δt to T/8 a fit needs: the largest term it reports
/// (a Gauss–Markov component, σ and T, on the white noise under it) has three parameters,
/// and its 99 % Δχ² gate needs two degrees of freedom left beyond them.
pub const MIN_OCTAVES: u32 = 5;

/// Fewest samples: octaves m = 1 … 2^(MIN_OCTAVES−1) all at most T/8.
pub const MIN_SAMPLES: u64 = 8 << (MIN_OCTAVES - 1);

/// Largest relative deviation of a time step from the mean step (as `analyze` warns).
pub const STEP_TOLERANCE: f64 = crate::analysis::passes::STEP_TOLERANCE;

/// A gyro block mean farther than this from the channel's median is motion (rad/s: 1 deg/s),
/// unless the noise of a block mean allows more ([`NOISE_MARGIN`]).
pub const GYRO_MOTION: f64 = std::f64::consts::PI / 180.0;

/// An accelerometer block-mean vector turned by more than this from the median vector is a
/// change of attitude (rad: 2°), unless the noise allows more.
pub const TILT_MOTION: f64 = 2.0 * std::f64::consts::PI / 180.0;

/// An accelerometer block-mean magnitude this far from the median's is a linear
/// acceleration (m/s²: 0.05 g), unless the noise allows more.
pub const ACCEL_MOTION: f64 = 0.05 * G0;

/// Block-mean noise allowance, in white-noise scatters of a block mean ([`white_scatter`]):
/// the largest of ≤ 4096 Gaussian block means lies within 5σ of the median with odds
/// 1 − 1e-3; the margin leaves room for noise that is not white at Δt (a filter's roll-off
/// lowers σ(Δt) by at most a factor 2 on the units tried).
pub const NOISE_MARGIN: f64 = 20.0;

/// Why a record is refused.
pub fn check(a: &Analysis) -> Result<(), String> {
    too_short(a)?;
    uniform(a)?;
    static_record(a)
}

fn too_short(a: &Analysis) -> Result<(), String> {
    if a.samples < MIN_SAMPLES {
        return Err(format!(
            "{} samples are too few to fit: the terms `fit` reports need at least {MIN_SAMPLES} ({MIN_OCTAVES} octaves of Allan deviation from Δt to T/8; a Gauss–Markov term, σ and T over the white noise, has three parameters and its 99 % gate two degrees of freedom more)",
            a.samples
        ));
    }
    Ok(())
}

fn uniform(a: &Analysis) -> Result<(), String> {
    let (smin, smax) = a.step_range;
    if !(smin.is_finite() && smax.is_finite()) {
        return Ok(());
    }
    let off = |s: f64| (s / a.dt - 1.0).abs();
    let (step, (k, t)) = if off(smin) >= off(smax) {
        (smin, a.step_at[0])
    } else {
        (smax, a.step_at[1])
    };
    if off(step) > STEP_TOLERANCE {
        return Err(format!(
            "sample {} (t = {t} s) comes {step} s after the one before it, where the mean step is {} s: `fit` needs uniformly sampled data (steps within ±{:.0} %); steps range from {smin} s to {smax} s. If the samples are uniform and only their time tags are not (host time of a buffered read), skip the time column (--columns with `-` for it) and give --rate",
            k + 1,
            a.dt,
            100.0 * STEP_TOLERANCE
        ));
    }
    Ok(())
}

/// The scatter of a mean of `len` samples of channel `ch` were its noise white at the level of
/// its first octave: σ(Δt)/√len. Not the Allan deviation at the block length, which motion
/// itself inflates (it would excuse the motion it should reveal); a static unit's slow drift
/// over the record is what the absolute thresholds allow for.
fn white_scatter(a: &Analysis, ch: usize, len: usize) -> f64 {
    a.channels[ch].adev.first().map_or(0.0, |p| p.adev) / (len as f64).sqrt()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn static_record(a: &Analysis) -> Result<(), String> {
    let Some(blocks) = &a.blocks else {
        return Ok(());
    };
    // Blocks of about a second (at least what the accumulator holds, at most an eighth of
    // the record): a second of rotation or tilt is what a unit that was moved shows, and
    // averaging that long takes the white noise out of the comparison.
    let held = blocks.means();
    let mut factor = 1usize;
    while ((blocks.block_len() * factor * 2) as f64) * a.dt <= 1.0 && held.len() / (factor * 2) >= 8
    {
        factor *= 2;
    }
    let means: Vec<[f64; 6]> = held
        .chunks_exact(factor)
        .map(|c| std::array::from_fn(|i| c.iter().map(|b| b[i]).sum::<f64>() / factor as f64))
        .collect();
    if means.len() < 2 {
        return Ok(());
    }
    let len = blocks.block_len() * factor;
    let span = |i: usize| {
        let t0 = (i * len) as f64 * a.dt;
        format!(
            "samples {}–{} (t = {} … {} s from the start)",
            i * len + 1,
            (i + 1) * len,
            crate::fit::template::sig4(t0),
            crate::fit::template::sig4(t0 + len as f64 * a.dt)
        )
    };
    for ch in 0..3 {
        let mid = median(means.iter().map(|m| m[ch]).collect());
        let allow = GYRO_MOTION.max(NOISE_MARGIN * white_scatter(a, ch, len));
        let (i, dev) = means
            .iter()
            .map(|m| (m[ch] - mid).abs())
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .expect("two blocks");
        if dev > allow {
            return Err(format!(
                "not a static recording: the mean of {} over {} is {} deg/s from its median (a unit at rest stays within {} deg/s); `fit` models a unit at rest",
                CHANNELS[ch],
                span(i),
                crate::fit::template::sig4(dev.to_degrees()),
                crate::fit::template::sig4(allow.to_degrees())
            ));
        }
    }
    let mid: [f64; 3] = std::array::from_fn(|i| median(means.iter().map(|m| m[3 + i]).collect()));
    let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    let g = norm(mid);
    let noise = (3..6)
        .map(|ch| white_scatter(a, ch, len))
        .fold(0.0, f64::max)
        * NOISE_MARGIN;
    for (i, m) in means.iter().enumerate() {
        let v = [m[3], m[4], m[5]];
        let n = norm(v);
        let tilt = if g > 0.0 && n > 0.0 {
            let c = (v[0] * mid[0] + v[1] * mid[1] + v[2] * mid[2]) / (n * g);
            c.clamp(-1.0, 1.0).acos()
        } else {
            0.0
        };
        let tilt_allow = TILT_MOTION.max(if g > 0.0 { noise / g } else { 0.0 });
        if tilt > tilt_allow {
            return Err(format!(
                "not a static recording: the accelerometer's mean over {} points {}° away from its median direction (a unit at rest stays within {}°); `fit` models a unit at rest",
                span(i),
                crate::fit::template::sig4(tilt.to_degrees()),
                crate::fit::template::sig4(tilt_allow.to_degrees())
            ));
        }
        let accel_allow = ACCEL_MOTION.max(noise);
        if (n - g).abs() > accel_allow {
            return Err(format!(
                "not a static recording: the accelerometer's mean magnitude over {} is {} g from its median (a unit at rest stays within {} g); `fit` models a unit at rest",
                span(i),
                crate::fit::template::sig4((n - g).abs() / G0),
                crate::fit::template::sig4(accel_allow / G0)
            ));
        }
    }
    Ok(())
}
