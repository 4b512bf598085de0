//! The unit's output filter read from the roll-off of its PSD towards the Nyquist frequency.
//!
//! A unit that samples at an internal rate D/Δt, low-passes and keeps every D-th value puts
//! out white noise whose density is the filter's |H|² folded onto the output band:
//! S(f)/S(0) = [`WhiteAllan::psd_ratio`] (exact for the generator's `[output_filter]`,
//! `docs/fidelity.md`). Over the top of the band (from a tenth of the Nyquist frequency, where
//! white noise is what a unit's PSD shows) each candidate filter is fitted to the six
//! channels' band-averaged PSDs with a free level per channel: ln P̂ = ln(c·ratio(f) + k(f)),
//! k the quantization density the value lattice fixes ([`OutputStage::quantization_psd`]; on
//! an ADIS16405's accelerometers a tenth of σ² at τ = Δt, which flattens their roll-off), each
//! band weighted by ν/2 (Var ln P̂ = 2/ν for a Welch mean of ν degrees of freedom,
//! [`crate::analysis::psd_band::WelchEdf`]); the short-τ Allan variance adds its χ² where no
//! resonance bends it. The best candidate is kept when it lowers that χ² below the flat
//! spectrum's by more than [`FILTER_PENALTY`]; the white-noise basis of the Allan-variance fit
//! is then the filtered one, N²·r(m)/τ ([`WhiteAllan::ratio`]). The gyros and the
//! accelerometers are scored apart, and the accelerometers get a filter of their own (same
//! internal rate and read, as `[output_filter.accel]` holds it) when that gains another
//! [`FILTER_PENALTY`] over the best single filter.
//!
//! Candidates: internal rates
//! D ∈ {2, 4, 8, 16} times the output rate with a moving average of L taps, or a CIC
//! (cascaded moving averages, the Bartlett window of the ADIS164xx family at order 2) of
//! order 2 or 3, L from 2 to 4D; the same kinds, L from 2 to 32, at [`POLLED_RATES_HZ`] read
//! by a polling host when the output rate does not divide it ([`ReadRatio`]); and Butterworth
//! low-passes of order 1–4 at D ∈ {1, 2, 4}, cut-off 5–45 % of the output rate.

use super::output::OutputStage;
use crate::analysis::analyzer::Analysis;
use crate::analysis::psd_band::{WelchEdf, banded};
use crate::errors::filter_allan::{SensorAllan, WhiteAllan};
use crate::errors::output_filter::{FilterKind, FilterSpec};
use crate::timing::ReadRatio;

/// χ² a filter must gain over a flat spectrum (χ²₃ at 99.9 %: kind, D and L chosen).
pub const FILTER_PENALTY: f64 = 16.27;

/// Lowest frequency of the roll-off fit, as a fraction of the Nyquist frequency.
pub const FROM_NYQUIST: f64 = 0.1;

/// Bands per decade of the roll-off fit.
const BANDS_PER_DECADE: f64 = 20.0;

/// A filter read from the PSD (or a table's Allan deviation), with the samples it reads.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedFilter {
    /// The filter (internal rate and kind).
    pub spec: FilterSpec,
    /// The internal samples the outputs read (a decimation, or a host's polled read).
    pub read: ReadRatio,
    /// The χ² of the fit and of a flat spectrum over the same bands.
    pub chi2: f64,
    /// χ² of the flat spectrum.
    pub flat_chi2: f64,
    /// χ² of the best single filter for both sensors (`chi2` when that is the one kept).
    pub shared_chi2: f64,
    /// PSD bands and Allan-deviation points fitted (all channels).
    pub bands: usize,
    /// Read from a table's shortest τ ([`fit_adev`]) rather than the PSD's roll-off.
    pub from_adev: bool,
    /// Per channel the post-filter floor ([`floors`]).
    pub floors: [Floor; 6],
}

impl FittedFilter {
    /// Each sensor's filtered white-noise Allan variance at the output rate.
    pub fn white(&self) -> SensorAllan {
        SensorAllan::new(&self.spec, self.read)
    }

    /// A filter known exactly (no χ², no floors), for the unit tests of what uses one.
    #[cfg(test)]
    pub(crate) fn known(spec: FilterSpec, read: ReadRatio) -> FittedFilter {
        FittedFilter {
            spec,
            read,
            chi2: 0.0,
            flat_chi2: 0.0,
            shared_chi2: 0.0,
            bands: 0,
            from_adev: false,
            floors: [Floor::default(); 6],
        }
    }
}

/// Internal rates of units commonly read by a host at a rate they are no multiple of: the
/// ADIS164xx family samples at 819.2 Hz (Analog Devices ADIS16405 and ADIS16448 data sheets)
/// and is often read at 100 or 200 Hz.
pub const POLLED_RATES_HZ: [f64; 1] = [819.2];

/// How far a recording's rate may be from a polled unit's nominal one (relative): two crystal
/// clocks differ by a few ppm (the ADIS16448 table's τ column gives 199.999861 Hz, 0.7 ppm from
/// 200 Hz).
pub const CLOCK_TOLERANCE: f64 = 2e-6;

/// The moving averages and CICs of order 2 and 3 of 2 to `max_taps` taps at `internal_hz`.
fn averagers(
    internal_hz: f64,
    read: ReadRatio,
    max_taps: usize,
    out: &mut Vec<(FilterSpec, ReadRatio)>,
) {
    for taps in 2..=max_taps {
        let kinds = [
            FilterKind::MovingAverage { taps },
            FilterKind::Cic { order: 2, taps },
            FilterKind::Cic { order: 3, taps },
        ];
        for kind in kinds {
            let spec = FilterSpec {
                internal_rate_hz: internal_hz,
                kind,
                accel: None,
            };
            out.push((spec, read));
        }
    }
}

/// The candidate filters at output interval Δt, with the internal samples their outputs read.
pub fn candidates(dt: f64) -> Vec<(FilterSpec, ReadRatio)> {
    let mut out = Vec::new();
    for d in [2u64, 4, 8, 16] {
        averagers(
            d as f64 / dt,
            ReadRatio::integer(d),
            4 * d as usize,
            &mut out,
        );
    }
    // A host's polled read of a unit whose internal rate is no multiple of the output rate.
    // The recording's rate is the host's clock (or a table's τ column): within
    // [`CLOCK_TOLERANCE`] of the ratio, the internal rate is taken as that ratio times it.
    for rate in POLLED_RATES_HZ {
        if let Some(read) = ReadRatio::approximating(rate * dt, CLOCK_TOLERANCE)
            && read.as_integer().is_none()
        {
            averagers(read.value() / dt, read, 32, &mut out);
        }
    }
    // IIR low-passes (a MEMS unit's digital low-pass is often one): Butterworth of order 1–4,
    // cut-off from 5 % to 45 % of the output rate, run at 1, 2 or 4 times the output rate.
    for d in [1u64, 2, 4] {
        for order in 1..=4 {
            for k in 1..=9 {
                let cutoff_hz = 0.05 * k as f64 / dt;
                if cutoff_hz < 0.45 * d as f64 / dt {
                    let spec = FilterSpec {
                        internal_rate_hz: d as f64 / dt,
                        kind: FilterKind::Butterworth { order, cutoff_hz },
                        accel: None,
                    };
                    out.push((spec, ReadRatio::integer(d)));
                }
            }
        }
    }
    out
}

/// A band of the top-of-band PSD or a short-τ Allan-variance point: where (f in Hz, or the
/// cluster size m), the estimate (ln P̂, or σ̂²), its weight (ν/2, or edf/2) and the known
/// quantization part of the model there (one-sided density, or Allan variance).
type Point = (f64, f64, f64, f64);

/// The top-of-band PSD of each channel: (f, ln P̂, weight ν/2, quantization density) per band,
/// leaving out the bands inside the channel's ranges of `exclude` (Hz; its broad resonances).
/// Banded once per recording and ranges ([`roll_off`]), and read under each quantizer
/// ([`fit_roll_off`]) and against each fitted model ([`psd_misfit`]).
pub struct RollOff(Vec<Vec<Point>>, Vec<Vec<(f64, f64)>>);

/// The recording's [`RollOff`], no quantization density set.
pub fn roll_off(a: &Analysis, exclude: &[Vec<(f64, f64)>]) -> RollOff {
    let nyquist = 0.5 / a.dt;
    RollOff(
        a.channels
            .iter()
            .enumerate()
            .map(|(ch, c)| {
                let skip = exclude.get(ch).map_or(&[][..], Vec::as_slice);
                let p = &c.psd;
                if p.segments == 0 || p.freq.len() < 3 {
                    return Vec::new();
                }
                let end = p.freq.len() - 1;
                let edf = WelchEdf::new(2 * end, p.segments);
                let b = banded(p, BANDS_PER_DECADE, 0.5);
                b.freq
                    .iter()
                    .zip(&b.density)
                    .zip(&b.bins)
                    .filter(|((f, d), _)| **f >= FROM_NYQUIST * nyquist && **d > 0.0)
                    .filter(|((f, _), _)| !skip.iter().any(|r| **f >= r.0 && **f <= r.1))
                    .map(|((&f, &d), &m)| (f, d.ln(), edf.edf(m) / 2.0, 0.0))
                    .collect()
            })
            .collect(),
        exclude.to_vec(),
    )
}

impl RollOff {
    /// The bands with the quantization density of `stages` (gyros, accelerometers) set.
    fn quantized(&self, stages: &[OutputStage; 2], dt: f64) -> Vec<Vec<Point>> {
        self.0
            .iter()
            .enumerate()
            .map(|(ch, b)| {
                let stage = &stages[ch / 3];
                b.iter()
                    .map(|&(f, y, w, _)| (f, y, w, stage.quantization_psd(f, dt)))
                    .collect()
            })
            .collect()
    }
}

/// χ² of the bands against ln(c·ratio(f) + k(f)), each channel's level c free and k its known
/// quantization density: a flat floor under the filtered white noise, which flattens the
/// roll-off where the filter has taken most of the noise (an ADIS16405's accelerometers: a
/// tenth of σ² at τ = Δt is their LSB's). Without k, ln c is the weighted mean of the residuals;
/// with it, Gauss–Newton on u = ln c from there (the model's slope in u is c·ratio/(c·ratio + k),
/// in (0, 1]), each step halved until χ² does not grow.
fn chi2(bands: &[Vec<Point>], ratio: impl Fn(usize, f64) -> f64) -> f64 {
    bands
        .iter()
        .enumerate()
        .map(|(i, ch)| {
            let s: Vec<f64> = ch.iter().map(|p| ratio(i, p.0)).collect();
            channel_chi2(ch, &s)
        })
        .sum()
}

/// [`chi2`] of one channel's bands against the shape `s` at them.
fn channel_chi2(ch: &[Point], s: &[f64]) -> f64 {
    let s: Vec<f64> = s.iter().map(|x| x.max(1e-300)).collect();
    let wsum: f64 = ch.iter().map(|p| p.2).sum();
    if wsum == 0.0 {
        return 0.0;
    }
    let cost = |u: f64| -> f64 {
        ch.iter()
            .zip(&s)
            .map(|(&(_, y, w, k), &s)| w * (y - (u.exp() * s + k).ln()).powi(2))
            .sum()
    };
    let mut u = ch
        .iter()
        .zip(&s)
        .map(|(p, s)| p.2 * (p.1 - s.ln()))
        .sum::<f64>()
        / wsum;
    let mut now = cost(u);
    if ch.iter().all(|p| p.3 == 0.0) {
        return now;
    }
    for _ in 0..50 {
        let (mut num, mut den) = (0.0, 0.0);
        for (&(_, y, w, k), &s) in ch.iter().zip(&s) {
            let signal = u.exp() * s;
            let slope = signal / (signal + k);
            num += w * (y - (signal + k).ln()) * slope;
            den += w * slope * slope;
        }
        let mut step = num / den;
        let mut next = cost(u + step);
        while next > now && step.abs() > 1e-15 {
            step *= 0.5;
            next = cost(u + step);
        }
        if next > now {
            break;
        }
        u += step;
        let gain = now - next;
        now = next;
        if gain <= 1e-12 * now.max(1.0) {
            break;
        }
    }
    now
}

/// χ² a channel's post-filter floor must gain to be kept (χ²₁ at 99.9 %: one level).
pub const FLOOR_PENALTY: f64 = 10.83;

/// How far past a resonance's range (as a factor on its edges) the floor fit leaves bands out.
const SKIRT: f64 = 1.25;

/// Largest floor sought, as a fraction of the filtered density's DC level: a floor that high
/// is no longer a detail of the roll-off but a different filter.
const MAX_FLOOR: f64 = 1.0;

/// A channel's white floor after the output filter ([`floors`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Floor {
    /// P²/N²: the post-filter noise over the filtered white noise's density (φ·r_∞); 0 when
    /// not kept.
    pub ratio: f64,
    /// Its standard deviation from the χ²'s curvature at the minimum (√(2/∂²χ²/∂φ²)·r_∞).
    pub sd: f64,
    /// The χ² the floor gained over none.
    pub gain: f64,
}

/// Each channel's white floor after the filter `f`: the top-of-band bands fitted to
/// ln(c·(ratio(f) + φ) + k(f)), the level c and the floor φ ≥ 0 free. A unit's axes need not
/// roll off alike under one filter (the ADIS16405's z accelerometer keeps more of its noise
/// near the Nyquist frequency than x and y: 7 % more at 44–50 Hz over 12–16 Hz on run 1); what
/// the filter leaves flat there is noise it did not shape. Kept when it lowers the channel's
/// χ² by more than [`FLOOR_PENALTY`].
pub fn floors(roll: &RollOff, stages: &[OutputStage; 2], dt: f64, f: &FittedFilter) -> [Floor; 6] {
    let bands = roll.quantized(stages, dt);
    let white = f.white();
    std::array::from_fn(|ch| {
        // A resonance's skirt reaches past the range where its excess is significant; a floor
        // is flat, so the bands next to a range (within a factor SKIRT) are left to it.
        let near = |hz: f64| {
            roll.1.get(ch).is_some_and(|r| {
                r.iter()
                    .any(|&(lo, hi)| hz >= lo / SKIRT && hz <= hi * SKIRT)
            })
        };
        let b: Vec<Point> = bands
            .get(ch)
            .map(|b| b.iter().copied().filter(|p| !near(p.0)).collect())
            .unwrap_or_default();
        // Two parameters (c, φ): with fewer than four bands the floor has too little to rest on.
        if b.len() < 4 {
            return Floor::default();
        }
        let b = &b;
        let w = white.channel(ch);
        let ratio: Vec<f64> = b.iter().map(|p| w.psd_ratio(p.0, dt)).collect();
        let at = |phi: f64| {
            let s: Vec<f64> = ratio.iter().map(|r| r + phi).collect();
            channel_chi2(b, &s)
        };
        let none = at(0.0);
        // χ² in φ is smooth with one minimum over the floors that matter; a scan on a
        // square-root grid brackets it and golden sections close in.
        let grid: Vec<f64> = (0..=40)
            .map(|j| MAX_FLOOR * (j as f64 / 40.0).powi(2))
            .collect();
        let j = (0..grid.len())
            .min_by(|&x, &y| at(grid[x]).total_cmp(&at(grid[y])))
            .expect("grid");
        let (mut lo, mut hi) = (grid[j.saturating_sub(1)], grid[(j + 1).min(40)]);
        let g = 0.5 * (5f64.sqrt() - 1.0);
        for _ in 0..60 {
            let (a, c) = (hi - g * (hi - lo), lo + g * (hi - lo));
            if at(a) < at(c) {
                hi = c;
            } else {
                lo = a;
            }
        }
        let phi = 0.5 * (lo + hi);
        let gain = (none - at(phi)).max(0.0);
        if gain <= FLOOR_PENALTY {
            return Floor {
                gain,
                ..Floor::default()
            };
        }
        // χ² is −2 ln L up to a constant, so Var φ̂ = 2/χ''; the second difference over a
        // step well inside the minimum's width (a hundredth of φ̂).
        let h = 0.01 * phi;
        let curvature = (at(phi + h) - 2.0 * at(phi) + at(phi - h)) / (h * h);
        let r = w.long_tau();
        Floor {
            ratio: phi * r,
            sd: (2.0 / curvature).sqrt() * r,
            gain,
        }
    })
}

/// The filter the recording's PSD shows (a published table, which has none: its short-τ
/// Allan deviation, [`fit_adev`]), if one earns its place.
pub fn fit(a: &Analysis) -> Option<FittedFilter> {
    fit_excluding(a, &[], &Default::default())
}

/// [`fit`] without the PSD bands inside each channel's ranges of `exclude` (Hz): a broad
/// resonance ([`super::resonance`]) in the top decade would bend the roll-off the filter is
/// read from. With `exclude` given per channel, the Allan variance at m ≤ [`ADEV_MAX_M`] of
/// the channels without a range adds its χ² ([`fit_adev`]'s) to the roll-off's. `stages`
/// (gyros, accelerometers) hold the quantization the recording's lattice shows, which adds to
/// the filtered noise in both.
pub fn fit_excluding(
    a: &Analysis,
    exclude: &[Vec<(f64, f64)>],
    stages: &[OutputStage; 2],
) -> Option<FittedFilter> {
    fit_roll_off(a, &roll_off(a, exclude), exclude, stages)
}

/// [`fit_excluding`] on the recording's [`RollOff`] for the same `exclude`, banded beforehand.
pub fn fit_roll_off(
    a: &Analysis,
    roll: &RollOff,
    exclude: &[Vec<(f64, f64)>],
    stages: &[OutputStage; 2],
) -> Option<FittedFilter> {
    let b = roll.quantized(stages, a.dt);
    let count: usize = b.iter().map(Vec::len).sum();
    if count < 4 {
        return fit_adev(a, exclude);
    }
    // Once the resonances are known (`exclude` names each channel's, none or some), the
    // short-τ Allan variance of the channels without one weighs in too: it holds the filter's
    // mark at τ = Δt … 64Δt, where the closure's bands are tightest, which the top decade of
    // the PSD alone leaves loose. Before (`exclude` empty) a bump would bend it.
    let pts: Vec<_> = adev_points(a, stages)
        .into_iter()
        .enumerate()
        .map(|(ch, p)| {
            let kept = exclude.get(ch).is_some_and(Vec::is_empty) && p.len() >= 4;
            if kept { p } else { Vec::new() }
        })
        .collect();
    let flat = chi2(&b, |_, _| 1.0) + adev_chi2(&pts, a.dt, &|_| 1.0);
    let count = count + pts.iter().map(Vec::len).sum::<usize>();
    let (bh, ph) = (halves(&b), halves(&pts));
    let mut f = best(a.dt, flat, count, false, |w, accel| {
        let k = usize::from(accel);
        chi2(bh[k], |_, f| w.psd_ratio(f, a.dt)) + adev_chi2(ph[k], a.dt, &|m| w.ratio(m))
    })?;
    f.floors = floors(roll, stages, a.dt, &f);
    Some(f)
}

/// χ² of the top-of-band PSD `roll` against each channel's model density `psd(ch, f)` (none:
/// the channel left out), its level free: what a fitted model says of the roll-off, which its
/// Allan variance alone leaves loose (a carried LSB's noise rising to the Nyquist frequency
/// under a steeper filter has nearly the Allan variance of a rounded one under the true
/// filter). The model holds the quantization, so the bands' own density is left at zero.
pub fn psd_misfit(roll: &RollOff, psd: impl Fn(usize, f64) -> Option<f64>) -> f64 {
    let mut b = roll.0.clone();
    for (ch, band) in b.iter_mut().enumerate() {
        if psd(ch, 1.0).is_none() {
            band.clear();
        }
    }
    chi2(&b, |ch, f| psd(ch, f).unwrap_or(1.0))
}

/// The candidate of least χ² (`score(w, accel)`: the gyros' or the accelerometers' channels),
/// kept when it gains [`FILTER_PENALTY`] over `flat`. The accelerometers get a filter of their
/// own at the same internal rate and read ([`FilterSpec::accel`]) when the best such pair
/// gains [`FILTER_PENALTY`] more over the best single filter: a unit's sensors often have
/// bandwidths set apart, and one filter for both then fits neither. Not from a table's Allan
/// deviation (`from_adev`): there no candidate comes near the points' precision (χ² 60 per
/// point on the ADIS16448 table), so a second filter gains by trading misfits, and the
/// closure got worse (gyro x and y of that table: 77 of 83 τ inside, 82 with one filter).
fn best(
    dt: f64,
    flat: f64,
    bands: usize,
    from_adev: bool,
    score: impl Fn(&WhiteAllan, bool) -> f64,
) -> Option<FittedFilter> {
    let scored: Vec<(FilterSpec, ReadRatio, [f64; 2])> = candidates(dt)
        .into_iter()
        .map(|(spec, read)| {
            let w = WhiteAllan::new(&spec, read);
            let c = [score(&w, false), score(&w, true)];
            (spec, read, c)
        })
        .collect();
    let total = |c: &[f64; 2]| c[0] + c[1];
    let shared = scored
        .iter()
        .min_by(|x, y| total(&x.2).total_cmp(&total(&y.2)))?;
    // Per (internal rate, read): the gyros' best kind and the accelerometers' best kind.
    let same = |a: &(FilterSpec, ReadRatio, [f64; 2]), b: &(FilterSpec, ReadRatio, [f64; 2])| {
        a.0.internal_rate_hz == b.0.internal_rate_hz && a.1 == b.1
    };
    let mut pair: Option<(FilterSpec, ReadRatio, f64)> = None;
    for (i, g) in scored.iter().enumerate() {
        if scored[..i].iter().any(|x| same(x, g)) {
            continue;
        }
        let by = |k: usize| {
            scored
                .iter()
                .filter(|x| same(x, g))
                .min_by(|x, y| x.2[k].total_cmp(&y.2[k]))
                .expect("the group holds g")
        };
        let (gyro, accel) = (by(0), by(1));
        let split = gyro.2[0] + accel.2[1];
        if gyro.0.kind != accel.0.kind && pair.as_ref().is_none_or(|p| split < p.2) {
            let spec = FilterSpec {
                accel: Some(accel.0.kind.clone()),
                ..gyro.0.clone()
            };
            pair = Some((spec, gyro.1, split));
        }
    }
    let chosen = match pair {
        Some(p) if !from_adev && total(&shared.2) - p.2 > FILTER_PENALTY => p,
        _ => (shared.0.clone(), shared.1, total(&shared.2)),
    };
    (flat - chosen.2 > FILTER_PENALTY).then_some(FittedFilter {
        shared_chi2: total(&shared.2),
        spec: chosen.0,
        read: chosen.1,
        chi2: chosen.2,
        flat_chi2: flat,
        bands,
        from_adev,
        floors: [Floor::default(); 6],
    })
}

/// The two sensors' halves of per-channel data (gyro x y z, accel x y z).
fn halves<T>(v: &[T]) -> [&[T]; 2] {
    let k = v.len().min(3);
    [&v[..k], &v[k..]]
}

/// A filter kind's template keys.
fn kind_toml(kind: &FilterKind) -> String {
    match kind {
        FilterKind::MovingAverage { taps } => format!("kind = \"moving_average\"\ntaps = {taps}"),
        FilterKind::Cic { order, taps } => {
            format!("kind = \"cic\"\norder = {order}\ntaps = {taps}")
        }
        FilterKind::Fir { coefficients } => {
            format!("kind = \"fir\"\ncoefficients = {coefficients:?}")
        }
        FilterKind::Butterworth { order, cutoff_hz } => {
            format!("kind = \"butterworth\"\norder = {order}\ncutoff = \"{cutoff_hz} Hz\"")
        }
    }
}

/// The `[output_filter]` table of a fitted filter.
pub fn toml(f: &FittedFilter) -> String {
    let kind = kind_toml(&f.spec.kind);
    let accel = match &f.spec.accel {
        None => String::new(),
        Some(k) => format!(
            "\n# The accelerometers' own filter: with it χ² {:.1}, with one filter for both {:.1} (kept when it gains more than {FILTER_PENALTY}).\n[output_filter.accel]\n{}\n",
            f.chi2,
            f.shared_chi2,
            kind_toml(k)
        ),
    };
    let source = if f.from_adev {
        format!(
            "the Allan deviation at m ≤ {ADEV_MAX_M} (docs/fit.md): χ² {:.1} over {} points",
            f.chi2, f.bands
        )
    } else {
        format!(
            "the PSD roll-off above {:.0} % of the Nyquist frequency and the short-τ Allan variance\n# of the channels without a resonance (docs/fit.md): χ² {:.1} over {} bands and points",
            100.0 * FROM_NYQUIST,
            f.chi2,
            f.bands
        )
    };
    // A polled read: say which samples the host gets, as the template alone implies it.
    let read = match f.read.as_integer() {
        Some(_) => String::new(),
        None => format!(
            "# Read by a polling host: output k is internal sample ⌊k·{}/{}⌋, the newest (docs/fidelity.md#output-filters).\n",
            f.read.internal_per_period(),
            f.read.period()
        ),
    };
    let floors: Vec<String> = f
        .floors
        .iter()
        .zip(crate::analysis::analyzer::CHANNELS)
        .filter(|(x, _)| x.gain > 0.0)
        .map(|(x, name)| {
            if x.ratio > 0.0 {
                format!("{name} {:.4} ± {:.4} (Δχ² {:.1})", x.ratio, x.sd, x.gain)
            } else {
                format!("{name} none (Δχ² {:.1})", x.gain)
            }
        })
        .collect();
    let floors = if floors.is_empty() {
        String::new()
    } else {
        format!(
            "# Post-filter floor per channel, P²/N² ± 1σ (kept when it gains more than {FLOOR_PENALTY}): {}.\n",
            floors.join(", ")
        )
    };
    format!(
        "\n# Output filter read from {source}\n# against {:.1} for a flat spectrum (kept when it gains more than {FILTER_PENALTY}).\n{read}{floors}[output_filter]\ninternal_rate_hz = {}\n{kind}\n{accel}",
        f.flat_chi2, f.spec.internal_rate_hz
    )
}

/// Longest cluster size the Allan-deviation filter fit uses: the filter's mark fades as 1/τ
/// ([`WhiteAllan::ratio`]), and beyond a few dozen samples the slow terms take over.
pub const ADEV_MAX_M: usize = 64;

/// The filter read from the Allan deviation at its shortest τ (m ≤ [`ADEV_MAX_M`]), where a
/// table gives nothing else to read it from: per channel σ̂²(m) = N²·r(m)/τ + C, N² and a
/// constant C (the slow terms, nearly flat over these τ) fitted by least squares on the
/// relative residuals with weights edf/2 (Var σ̂²/σ² = 2/edf, white-noise edf); the candidate
/// with the least χ² over the six channels is kept when it gains [`FILTER_PENALTY`] over
/// r ≡ 1. The channels with a broad resonance in `exclude` are left out (its Allan variance
/// would bend the filter's mark), as long as one of each sensor stays.
pub fn fit_adev(a: &Analysis, exclude: &[Vec<(f64, f64)>]) -> Option<FittedFilter> {
    let mut chans = adev_points(a, &Default::default());
    if chans.iter().any(|c| c.len() < 4) {
        return None;
    }
    let bump = |ch: usize| exclude.get(ch).is_some_and(|r| !r.is_empty());
    for base in [0, 3] {
        if (base..base + 3).any(|ch| !bump(ch)) {
            (base..base + 3)
                .filter(|&ch| bump(ch))
                .for_each(|ch| chans[ch].clear());
        }
    }
    let count: usize = chans.iter().map(Vec::len).sum();
    let flat = adev_chi2(&chans, a.dt, &|_| 1.0);
    let half = halves(&chans);
    best(a.dt, flat, count, true, |w, accel| {
        adev_chi2(half[usize::from(accel)], a.dt, &|m| w.ratio(m))
    })
}

/// Each channel's Allan variance at m ≤ [`ADEV_MAX_M`] (and ≤ n/8): (m, σ̂², weight edf/2,
/// the quantization's Allan variance in `stages`).
fn adev_points(a: &Analysis, stages: &[OutputStage; 2]) -> Vec<Vec<Point>> {
    let n = a.samples as usize;
    a.channels
        .iter()
        .enumerate()
        .map(|(ch, c)| {
            c.adev
                .iter()
                .filter(|p| p.m <= ADEV_MAX_M && p.m <= n / 8 && p.adev > 0.0)
                .map(|p| {
                    let w = crate::analysis::confidence::edf(
                        crate::analysis::confidence::NoiseType::WhiteRate,
                        n + 1,
                        p.m,
                    ) / 2.0;
                    let known = stages[ch / 3].known(p.m, a.dt);
                    (p.m as f64, p.adev * p.adev, w, known)
                })
                .collect()
        })
        .collect()
}

/// χ² of the channels' points against N²·r(m)/τ + C + K(m), N² and C free per channel and K
/// the known quantization.
fn adev_chi2(chans: &[Vec<Point>], dt: f64, ratio: &dyn Fn(usize) -> f64) -> f64 {
    chans
        .iter()
        .filter(|pts| !pts.is_empty())
        .map(|pts| {
            // Minimise Σ w (1 − K/y − (x·u + C·v))² over (x, C), u = r(m)/(τy), v = 1/y: 2×2
            // normal equations.
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &(m, y, w, k) in pts {
                let u = ratio(m as usize) / (m * dt) / y;
                let v = 1.0 / y;
                let t = 1.0 - k / y;
                a11 += w * u * u;
                a12 += w * u * v;
                a22 += w * v * v;
                b1 += w * u * t;
                b2 += w * v * t;
            }
            let det = a11 * a22 - a12 * a12;
            let (x, c) = ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det);
            pts.iter()
                .map(|&(m, y, w, k)| {
                    let model = x * ratio(m as usize) / (m * dt) + c + k;
                    w * (1.0 - model / y).powi(2)
                })
                .sum::<f64>()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bands drawn exactly from ln(c·(ratio + φ)) under a moving average of 10 taps at 4× the
    /// output rate (r_∞ = 1.04: 100 and 300 Hz are no nulls of it) give back φ·r_∞ as P²/N²
    /// to 1e-6 on the channels that have one (φ = 0.05 on gyro z and accel x, with different
    /// levels c), and no floor on the others.
    #[test]
    fn floors_are_read_back_from_exact_bands() {
        let dt = 0.01;
        let spec = FilterSpec {
            internal_rate_hz: 400.0,
            kind: FilterKind::MovingAverage { taps: 10 },
            accel: None,
        };
        let f = FittedFilter::known(spec, ReadRatio::integer(4));
        let w = f.white();
        let phi = [0.0, 0.0, 0.05, 0.05, 0.0, 0.0];
        let roll = RollOff(
            (0..6)
                .map(|ch| {
                    let c = 1e-3 * (ch + 1) as f64;
                    (0..20)
                        .map(|j| {
                            let hz = 5.0 + 2.25 * j as f64;
                            let r = w.channel(ch).psd_ratio(hz, dt);
                            (hz, (c * (r + phi[ch])).ln(), 500.0, 0.0)
                        })
                        .collect()
                })
                .collect(),
            Vec::new(),
        );
        let got = floors(&roll, &Default::default(), dt, &f);
        for ch in 0..6 {
            let want = phi[ch] * w.channel(ch).long_tau();
            assert!(
                (got[ch].ratio - want).abs() < 1e-6,
                "channel {ch}: {:?} vs {want}",
                got[ch]
            );
        }
    }

    /// A resonance's skirt is not read as a floor: bands drawn exactly from ln(c·ratio) with a
    /// range of 25–38 Hz left out, and the bands above it up to 47.5 Hz lifted 15 % as a skirt
    /// lifts them, give no floor, since the bands within a factor [`SKIRT`] of the range
    /// are left to it. Read with them, the lift passes for a floor (kept).
    #[test]
    fn a_resonance_skirt_is_not_read_as_a_floor() {
        let dt = 0.01;
        let f = FittedFilter::known(
            FilterSpec {
                internal_rate_hz: 400.0,
                kind: FilterKind::MovingAverage { taps: 10 },
                accel: None,
            },
            ReadRatio::integer(4),
        );
        let w = f.white();
        let range = (25.0, 38.0);
        let bands: Vec<Point> = (0..40)
            .map(|j| 5.0 + 1.125 * j as f64)
            .filter(|hz| !(*hz >= range.0 && *hz <= range.1))
            .map(|hz| {
                let lift = if hz > range.1 && hz < 47.5 { 1.15 } else { 1.0 };
                (
                    hz,
                    (1e-3 * w.channel(0).psd_ratio(hz, dt) * lift).ln(),
                    500.0,
                    0.0,
                )
            })
            .collect();
        let with = |ranges: Vec<Vec<(f64, f64)>>| {
            floors(
                &RollOff(vec![bands.clone()], ranges),
                &Default::default(),
                dt,
                &f,
            )[0]
        };
        let skirt = with(vec![vec![range]]);
        assert_eq!(skirt.ratio, 0.0, "{skirt:?}");
        let blind = with(vec![Vec::new()]);
        assert!(blind.ratio > 0.0 && blind.gain > FLOOR_PENALTY, "{blind:?}");
    }

    /// The roll-off's χ² finds each channel's level under a known quantization floor: bands
    /// drawn exactly from ln(c·ratio + k) give χ² at round-off, for a level c it starts far
    /// from (the floor is half the density at the top band); the same bands read with no
    /// floor leave a misfit; the shape's scale is the level's, so twice the ratio fits as well.
    #[test]
    fn chi2_fits_the_level_under_a_known_floor() {
        let ratio = |ch: usize, f: f64| 1.0 / (1.0 + (f / (10.0 + ch as f64)).powi(4));
        let bands = |floor: bool| -> Vec<Vec<Point>> {
            (0..2)
                .map(|ch| {
                    let c = 3e-6 * (ch + 1) as f64;
                    let k = c * ratio(ch, 50.0);
                    (0..40)
                        .map(|i| {
                            let f = 5.0 + 45.0 * i as f64 / 39.0;
                            let y = (c * ratio(ch, f) + k).ln();
                            (f, y, 50.0, if floor { k } else { 0.0 })
                        })
                        .collect()
                })
                .collect()
        };
        let exact = chi2(&bands(true), ratio);
        assert!(exact < 1e-20, "{exact}");
        let without = chi2(&bands(false), ratio);
        assert!(without > 1.0, "{without}");
        let scaled = chi2(&bands(true), |ch, f| 2.0 * ratio(ch, f));
        assert!(scaled < 1e-20, "{scaled}");
    }

    /// The short-τ Allan variance's χ² subtracts the known quantization: points drawn exactly
    /// from x·r(m)/τ + C + K(m) give χ² at round-off, and without K a misfit.
    #[test]
    fn adev_chi2_takes_the_known_part() {
        let (dt, x, c) = (0.01, 2e-6, 1e-9);
        let r = |m: usize| 1.0 - 0.4 / m as f64;
        let pts = |known: bool| -> Vec<Vec<Point>> {
            // A carried LSB of 1 °/s: 3Q²/τ² is 6 % of σ² at m = 64 and 86 % at m = 1.
            let stage = OutputStage::carried(1f64.to_radians(), dt);
            vec![
                [1usize, 2, 4, 8, 16, 32, 64]
                    .iter()
                    .map(|&m| {
                        let k = stage.known(m, dt);
                        let y = x * r(m) / (m as f64 * dt) + c + k;
                        (m as f64, y, 10.0, if known { k } else { 0.0 })
                    })
                    .collect(),
            ]
        };
        let exact = adev_chi2(&pts(true), dt, &r);
        assert!(exact < 1e-20, "{exact}");
        let without = adev_chi2(&pts(false), dt, &r);
        assert!(without > 1e-3, "{without}");
    }

    /// The table `fit` writes reads back as the same filter, the accelerometers' own included.
    #[test]
    fn the_written_table_reads_back() {
        for accel in [None, Some(FilterKind::MovingAverage { taps: 8 })] {
            let spec = FilterSpec {
                internal_rate_hz: 819.2,
                kind: FilterKind::Butterworth {
                    order: 2,
                    cutoff_hz: 30.0,
                },
                accel,
            };
            let f = FittedFilter {
                spec: spec.clone(),
                read: ReadRatio::from_rates(819.2, 100.0).unwrap(),
                chi2: 1.0,
                flat_chi2: 100.0,
                shared_chi2: 1.0,
                bands: 10,
                from_adev: false,
                floors: [Floor::default(); 6],
            };
            let text = toml(&f);
            let t: toml::Table = text.parse().unwrap();
            let table = t["output_filter"].as_table().unwrap();
            let back = crate::errors::output_filter::from_toml(table).unwrap();
            assert_eq!(back, spec, "{text}");
        }
    }
}
