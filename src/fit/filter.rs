//! The unit's output filter read from the roll-off of its PSD towards the Nyquist frequency.
//!
//! A unit that samples at an internal rate D/Δt, low-passes and keeps every D-th value puts
//! out white noise whose density is the filter's |H|² folded onto the output band:
//! S(f)/S(0) = [`WhiteAllan::psd_ratio`] (exact for the generator's `[output_filter]`,
//! `docs/fidelity.md`). Over the top of the band (from a tenth of the Nyquist frequency, where
//! white noise is what a unit's PSD shows) each candidate filter is fitted to the six
//! channels' band-averaged PSDs with a free level per channel: ln P̂ = ln c + ln ratio(f), each
//! band weighted by ν/2 (Var ln P̂ = 2/ν for a Welch mean of ν degrees of freedom,
//! [`crate::analysis::psd_band::WelchEdf`]). The best candidate is kept when it lowers that χ²
//! below the flat spectrum's by more than [`FILTER_PENALTY`]; the white-noise basis of the
//! Allan-variance fit is then the filtered one, N²·r(m)/τ ([`WhiteAllan::ratio`]).
//!
//! Candidates (one filter for all six channels, as a template holds it): internal rates
//! D ∈ {2, 4, 8, 16} times the output rate with a moving average of L taps, or a CIC
//! (cascaded moving averages, the Bartlett window of the ADIS164xx family at order 2) of
//! order 2 or 3, L from 2 to 4D; the same kinds, L from 2 to 32, at [`POLLED_RATES_HZ`] read
//! by a polling host when the output rate does not divide it ([`ReadRatio`]); and Butterworth
//! low-passes of order 1–4 at D ∈ {1, 2, 4}, cut-off 5–45 % of the output rate.

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
    /// PSD bands and Allan-deviation points fitted (all channels).
    pub bands: usize,
    /// Read from a table's shortest τ ([`fit_adev`]) rather than the PSD's roll-off.
    pub from_adev: bool,
}

impl FittedFilter {
    /// Each sensor's filtered white-noise Allan variance at the output rate.
    pub fn white(&self) -> SensorAllan {
        SensorAllan::new(&self.spec, self.read)
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

/// The top-of-band PSD of each channel: (f, ln P̂, weight ν/2) per band, leaving out the
/// bands inside the channel's ranges of `exclude` (Hz; its broad resonances).
fn bands(a: &Analysis, exclude: &[Vec<(f64, f64)>]) -> Vec<Vec<(f64, f64, f64)>> {
    let nyquist = 0.5 / a.dt;
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
                .map(|((&f, &d), &m)| (f, d.ln(), edf.edf(m) / 2.0))
                .collect()
        })
        .collect()
}

/// χ² of the bands against a shape ln ratio(f), each channel's level free (its weighted mean).
fn chi2(bands: &[Vec<(f64, f64, f64)>], shape: impl Fn(f64) -> f64) -> f64 {
    bands
        .iter()
        .map(|ch| {
            let r: Vec<(f64, f64)> = ch.iter().map(|&(f, y, w)| (y - shape(f), w)).collect();
            let wsum: f64 = r.iter().map(|x| x.1).sum();
            if wsum == 0.0 {
                return 0.0;
            }
            let level = r.iter().map(|x| x.0 * x.1).sum::<f64>() / wsum;
            r.iter().map(|(e, w)| w * (e - level).powi(2)).sum::<f64>()
        })
        .sum()
}

/// The filter the recording's PSD shows (a published table, which has none: its short-τ
/// Allan deviation, [`fit_adev`]), if one earns its place.
pub fn fit(a: &Analysis) -> Option<FittedFilter> {
    fit_excluding(a, &[])
}

/// [`fit`] without the PSD bands inside each channel's ranges of `exclude` (Hz): a broad
/// resonance ([`super::resonance`]) in the top decade would bend the roll-off the filter is
/// read from. With `exclude` given per channel, the Allan variance at m ≤ [`ADEV_MAX_M`] of
/// the channels without a range adds its χ² ([`fit_adev`]'s) to the roll-off's.
pub fn fit_excluding(a: &Analysis, exclude: &[Vec<(f64, f64)>]) -> Option<FittedFilter> {
    let b = bands(a, exclude);
    let count: usize = b.iter().map(Vec::len).sum();
    if count < 4 {
        return fit_adev(a);
    }
    // Once the resonances are known (`exclude` names each channel's, none or some), the
    // short-τ Allan variance of the channels without one weighs in too: it holds the filter's
    // mark at τ = Δt … 64Δt, where the closure's bands are tightest, which the top decade of
    // the PSD alone leaves loose. Before (`exclude` empty) a bump would bend it.
    let pts: Vec<_> = adev_points(a)
        .into_iter()
        .enumerate()
        .filter(|(ch, p)| exclude.get(*ch).is_some_and(Vec::is_empty) && p.len() >= 4)
        .map(|x| x.1)
        .collect();
    let flat = chi2(&b, |_| 0.0) + adev_chi2(&pts, a.dt, &|_| 1.0);
    let count = count + pts.iter().map(Vec::len).sum::<usize>();
    best(a.dt, flat, count, false, |w| {
        chi2(&b, |f| w.psd_ratio(f, a.dt).max(1e-300).ln()) + adev_chi2(&pts, a.dt, &|m| w.ratio(m))
    })
}

/// The candidate of least χ² (`score`), kept when it gains [`FILTER_PENALTY`] over `flat`.
fn best(
    dt: f64,
    flat: f64,
    bands: usize,
    from_adev: bool,
    score: impl Fn(&WhiteAllan) -> f64,
) -> Option<FittedFilter> {
    let best = candidates(dt)
        .into_iter()
        .map(|(spec, read)| {
            let c = score(&WhiteAllan::new(&spec, read));
            (spec, read, c)
        })
        .min_by(|x, y| x.2.total_cmp(&y.2))?;
    (flat - best.2 > FILTER_PENALTY).then_some(FittedFilter {
        spec: best.0,
        read: best.1,
        chi2: best.2,
        flat_chi2: flat,
        bands,
        from_adev,
    })
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
    let accel = f.spec.accel.as_ref().map_or(String::new(), |k| {
        format!(
            "\n# The accelerometers' own filter.\n[output_filter.accel]\n{}\n",
            kind_toml(k)
        )
    });
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
    format!(
        "\n# Output filter read from {source}\n# against {:.1} for a flat spectrum (kept when it gains more than {FILTER_PENALTY}).\n{read}[output_filter]\ninternal_rate_hz = {}\n{kind}\n{accel}",
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
/// r ≡ 1.
pub fn fit_adev(a: &Analysis) -> Option<FittedFilter> {
    let chans = adev_points(a);
    let count: usize = chans.iter().map(Vec::len).sum();
    if chans.iter().any(|c| c.len() < 4) {
        return None;
    }
    let flat = adev_chi2(&chans, a.dt, &|_| 1.0);
    best(a.dt, flat, count, true, |w| {
        adev_chi2(&chans, a.dt, &|m| w.ratio(m))
    })
}

/// Each channel's Allan variance at m ≤ [`ADEV_MAX_M`] (and ≤ n/8): (m, σ̂², weight edf/2).
fn adev_points(a: &Analysis) -> Vec<Vec<(usize, f64, f64)>> {
    let n = a.samples as usize;
    a.channels
        .iter()
        .map(|c| {
            c.adev
                .iter()
                .filter(|p| p.m <= ADEV_MAX_M && p.m <= n / 8 && p.adev > 0.0)
                .map(|p| {
                    let w = crate::analysis::confidence::edf(
                        crate::analysis::confidence::NoiseType::WhiteRate,
                        n + 1,
                        p.m,
                    ) / 2.0;
                    (p.m, p.adev * p.adev, w)
                })
                .collect()
        })
        .collect()
}

/// χ² of the channels' points against N²·r(m)/τ + C, N² and C free per channel.
fn adev_chi2(chans: &[Vec<(usize, f64, f64)>], dt: f64, ratio: &dyn Fn(usize) -> f64) -> f64 {
    chans
        .iter()
        .map(|pts| {
            // Minimise Σ w (1 − (x·u + C)/y)² over (x, C), u = r(m)/τ: 2×2 normal equations.
            let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for &(m, y, w) in pts {
                let u = ratio(m) / (m as f64 * dt) / y;
                let v = 1.0 / y;
                a11 += w * u * u;
                a12 += w * u * v;
                a22 += w * v * v;
                b1 += w * u;
                b2 += w * v;
            }
            let det = a11 * a22 - a12 * a12;
            let (x, c) = ((b1 * a22 - b2 * a12) / det, (a11 * b2 - a12 * b1) / det);
            pts.iter()
                .map(|&(m, y, w)| {
                    let model = x * ratio(m) / (m as f64 * dt) + c;
                    w * (1.0 - model / y).powi(2)
                })
                .sum::<f64>()
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

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
                bands: 10,
                from_adev: false,
            };
            let text = toml(&f);
            let t: toml::Table = text.parse().unwrap();
            let table = t["output_filter"].as_table().unwrap();
            let back = crate::errors::output_filter::from_toml(table).unwrap();
            assert_eq!(back, spec, "{text}");
        }
    }
}
