//! A unit's output filter: real IMUs sample their sensors at an internal rate, low-pass filter
//! and decimate to the output rate, so their PSD rolls off and their noise at τ ≈ Δt is not
//! white. Pure math: the filter designs, their frequency response and DC group delay, and a
//! streaming filter-and-decimate over six channels (gyro x y z, accel x y z).
//!
//! | kind | response H(f) at internal rate f_s | DC group delay (samples) |
//! | --- | --- | --- |
//! | moving average of L taps | sin(πfL/f_s) / (L sin(πf/f_s)) | (L − 1)/2 |
//! | CIC of order R, length L (Hogenauer 1981) | the moving average's, to the power R | R(L − 1)/2 |
//! | FIR h_k (scaled to Σh = 1) | Σ h_k e^{−2πifk/f_s} | Σ k h_k |
//! | Butterworth of order n, cut-off f_c (bilinear, pre-warped) | \|H\|² = 1/(1 + (tan(πf/f_s)/tan(πf_c/f_s))^{2n}) | Σ over sections of grd B(1) − grd A(1) |
//!
//! Every kind has unit DC gain, so a constant rate passes unchanged. The DC group delay of a
//! polynomial P(z⁻¹) = Σ p_k z^{−k} is Σ k p_k / Σ p_k; a ramp input leaves any unit-gain
//! filter (after its transient) delayed by exactly that many samples, which is why it is the
//! sample's latency. The Butterworth sections are the standard bilinear-transform biquads
//! (e.g. R. Bristow-Johnson, "Cookbook formulae for audio EQ biquad filter coefficients",
//! low-pass with Q_k = 1/(2 sin((2k + 1)π/(2n)))), plus one first-order section for odd n.

use crate::timing::ReadRatio;
use std::f64::consts::PI;

/// The filter a template names (`[output_filter]`).
#[derive(Clone, Debug, PartialEq)]
pub enum FilterKind {
    /// Mean of the last `taps` internal samples.
    MovingAverage {
        /// Length L.
        taps: usize,
    },
    /// Cascaded integrator–comb: `order` moving averages of `taps` in cascade.
    Cic {
        /// Number of stages R.
        order: usize,
        /// Length L of each (decimation × differential delay).
        taps: usize,
    },
    /// FIR with the given coefficients (newest sample first), scaled to unit DC gain.
    Fir {
        /// h_0 … h_{N−1}.
        coefficients: Vec<f64>,
    },
    /// Butterworth low-pass.
    Butterworth {
        /// Order n (1–8).
        order: usize,
        /// Cut-off (−3 dB) frequency (Hz).
        cutoff_hz: f64,
    },
}

/// An output filter: the unit's internal rate and its filter.
#[derive(Clone, Debug, PartialEq)]
pub struct FilterSpec {
    /// Internal sampling rate (Hz): an integer multiple of the output rate (decimation), or
    /// any rate above it in a ratio of whole numbers (a host's polled read, [`ReadRatio`]).
    pub internal_rate_hz: f64,
    /// The filter, run at the internal rate (the gyros', and the accelerometers' unless
    /// `accel` names theirs).
    pub kind: FilterKind,
    /// The accelerometers' own filter at the same internal rate and read, when it differs
    /// from the gyros' (`[output_filter.accel]`): many units set each sensor's bandwidth
    /// apart (the BMI160's `ACC_CONF` and `GYR_CONF`, the MPU-6050's per-sensor DLPF).
    pub accel: Option<FilterKind>,
}

/// One second-order section y = (b0 + b1 z⁻¹ + b2 z⁻²)/(1 + a1 z⁻¹ + a2 z⁻²) x.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Biquad {
    b: [f64; 3],
    a: [f64; 2],
}

/// The designed filter: FIR taps or IIR sections.
#[derive(Clone, Debug, PartialEq)]
enum Design {
    Fir(Vec<f64>),
    Iir(Vec<Biquad>),
}

impl FilterKind {
    /// Lengths and orders in range, the cut-off below the internal Nyquist frequency.
    fn check(&self, internal_rate_hz: f64) -> Result<(), String> {
        match self {
            FilterKind::MovingAverage { taps } | FilterKind::Cic { taps, .. }
                if *taps == 0 || *taps > 65536 =>
            {
                Err(format!("taps = {taps}: expected 1 to 65536"))
            }
            FilterKind::Cic { order, .. } if *order == 0 || *order > 8 => {
                Err(format!("order = {order}: expected 1 to 8"))
            }
            FilterKind::Fir { coefficients } => {
                let s: f64 = coefficients.iter().sum();
                if coefficients.is_empty() || coefficients.len() > 65536 {
                    return Err("coefficients: expected 1 to 65536 numbers".into());
                }
                if !(s.is_finite() && s.abs() > 1e-12) {
                    return Err(
                        "coefficients: their sum (the DC gain) must be finite and non-zero".into(),
                    );
                }
                Ok(())
            }
            FilterKind::Butterworth { order, cutoff_hz } => {
                if *order == 0 || *order > 8 {
                    return Err(format!("order = {order}: expected 1 to 8"));
                }
                if !(*cutoff_hz > 0.0 && *cutoff_hz < 0.5 * internal_rate_hz) {
                    return Err(format!(
                        "cutoff {cutoff_hz} Hz: expected above 0 and below half the internal rate ({} Hz)",
                        0.5 * internal_rate_hz
                    ));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    fn design(&self, fs: f64) -> Design {
        match self {
            FilterKind::MovingAverage { taps } => Design::Fir(vec![1.0 / *taps as f64; *taps]),
            FilterKind::Cic { order, taps } => {
                let mut h = vec![1.0];
                let boxcar = vec![1.0 / *taps as f64; *taps];
                for _ in 0..*order {
                    h = convolve(&h, &boxcar);
                }
                Design::Fir(h)
            }
            FilterKind::Fir { coefficients } => {
                let s: f64 = coefficients.iter().sum();
                Design::Fir(coefficients.iter().map(|c| c / s).collect())
            }
            FilterKind::Butterworth { order, cutoff_hz } => {
                Design::Iir(butterworth(*order, *cutoff_hz, fs))
            }
        }
    }
}

fn convolve(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// Butterworth low-pass of order n at cut-off f_c for sampling rate f_s, as cascaded sections.
fn butterworth(n: usize, fc: f64, fs: f64) -> Vec<Biquad> {
    let k = (PI * fc / fs).tan();
    let mut s: Vec<Biquad> = (0..n / 2)
        .map(|i| {
            let inv_q = 2.0 * ((2 * i + 1) as f64 * PI / (2 * n) as f64).sin();
            let norm = 1.0 + k * inv_q + k * k;
            let b0 = k * k / norm;
            Biquad {
                b: [b0, 2.0 * b0, b0],
                a: [2.0 * (k * k - 1.0) / norm, (1.0 - k * inv_q + k * k) / norm],
            }
        })
        .collect();
    if n % 2 == 1 {
        let b0 = k / (1.0 + k);
        s.push(Biquad {
            b: [b0, b0, 0.0],
            a: [(k - 1.0) / (k + 1.0), 0.0],
        });
    }
    s
}

/// Σ k p_k / Σ p_k: the DC group delay of P(z⁻¹) (samples).
fn dc_delay(p: &[f64]) -> f64 {
    let num: f64 = p.iter().enumerate().map(|(k, v)| k as f64 * v).sum();
    num / p.iter().sum::<f64>()
}

impl FilterSpec {
    /// Checks the spec against the output rate and gives the samples the outputs read: the
    /// internal rate at least the output rate, in a ratio of whole numbers
    /// ([`ReadRatio::from_rates`]); lengths and orders in range, the cut-off below the
    /// internal Nyquist frequency.
    pub fn check(&self, output_rate_hz: f64) -> Result<ReadRatio, String> {
        let ratio = ReadRatio::from_rates(self.internal_rate_hz, output_rate_hz)?;
        self.kind.check(self.internal_rate_hz)?;
        if let Some(a) = &self.accel {
            a.check(self.internal_rate_hz)
                .map_err(|e| format!("accel: {e}"))?;
        }
        Ok(ratio)
    }

    /// The filter one sensor's channels run (`accel` false: the gyros'), as a spec of its own.
    pub fn sensor(&self, accel: bool) -> FilterSpec {
        let kind = match (&self.accel, accel) {
            (Some(a), true) => a.clone(),
            _ => self.kind.clone(),
        };
        FilterSpec {
            internal_rate_hz: self.internal_rate_hz,
            kind,
            accel: None,
        }
    }

    /// The filter of channel `ch` (0–2 gyro, 3–5 accel), as a spec of its own.
    pub fn channel(&self, ch: usize) -> FilterSpec {
        self.sensor(ch >= 3)
    }

    /// |H(f)| at frequency f (Hz), from the designed coefficients.
    pub fn magnitude(&self, f: f64) -> f64 {
        let w = 2.0 * PI * f / self.internal_rate_hz;
        let poly = |p: &[f64]| {
            p.iter().enumerate().fold((0.0, 0.0), |(re, im), (k, c)| {
                let x = w * k as f64;
                (re + c * x.cos(), im - c * x.sin())
            })
        };
        let abs = |(re, im): (f64, f64)| (re * re + im * im).sqrt();
        match self.kind.design(self.internal_rate_hz) {
            Design::Fir(h) => abs(poly(&h)),
            Design::Iir(s) => s
                .iter()
                .map(|q| abs(poly(&q.b)) / abs(poly(&[1.0, q.a[0], q.a[1]])))
                .product(),
        }
    }

    /// DC group delay (s): how far the filtered signal lags the internal samples (the gyros';
    /// [`FilterSpec::sensor`] for the accelerometers' own).
    pub fn latency_s(&self) -> f64 {
        let samples = match self.kind.design(self.internal_rate_hz) {
            Design::Fir(h) => dc_delay(&h),
            Design::Iir(s) => s
                .iter()
                .map(|q| dc_delay(&q.b) - dc_delay(&[1.0, q.a[0], q.a[1]]))
                .sum(),
        };
        samples / self.internal_rate_hz
    }

    /// How long before the end of its output interval an output sample is valid (s), in the
    /// sense of an unfiltered record: a ramp's filtered sample equals the ramp's mean over the
    /// output interval that ends that long before the sample's time tag.
    ///
    /// Each internal sample is the mean over its interval, so it equals a ramp at Δt_in/2
    /// before its end; the filter adds its DC group delay g; an unfiltered record equals the
    /// ramp at Δt_out/2 before its end. Hence g + Δt_in/2 − Δt_out/2, which is zero for a unit
    /// that sums exactly its D internal samples (a moving average of D taps).
    pub fn validity_offset_s(&self, output_rate_hz: f64) -> f64 {
        self.latency_s() + 0.5 / self.internal_rate_hz - 0.5 / output_rate_hz
    }

    /// Impulse response h_0 … h_{n−1} at the internal rate (exact for FIR, truncated IIR).
    pub fn impulse_response(&self, n: usize) -> Vec<f64> {
        let mut f = Filter::new(self, ReadRatio::integer(1));
        (0..n)
            .map(|k| {
                let x = if k == 0 { 1.0 } else { 0.0 };
                f.push([x; 6]).map_or(0.0, |y| y[0])
            })
            .collect()
    }
}

/// The streaming filter-and-read of six channels: push internal samples, get the filtered
/// value of each one an output reads (every D-th, or the polled ⌊k·p/q⌋-th, [`ReadRatio`]).
#[derive(Clone, Debug)]
pub struct Filter {
    /// The six channels' filter, or the gyros' when the accelerometers have their own.
    gyro: Bank,
    /// The accelerometers' own filter (`FilterSpec::accel`).
    accel: Option<Bank>,
    read: ReadRatio,
    /// Internal samples pushed, outputs given, and the internal sample the next output reads.
    pushed: u64,
    given: u64,
    next: u64,
}

/// One design's state over six channels.
#[derive(Clone, Debug)]
struct Bank {
    design: Design,
    /// FIR: the last N inputs per channel in a ring; IIR: two states per section and channel.
    state: Vec<[f64; 6]>,
    head: usize,
}

impl Bank {
    fn new(kind: &FilterKind, fs: f64) -> Bank {
        let design = kind.design(fs);
        let len = match &design {
            Design::Fir(h) => h.len(),
            Design::Iir(s) => 2 * s.len(),
        };
        Bank {
            design,
            state: vec![[0.0; 6]; len],
            head: 0,
        }
    }

    fn prime(&mut self, x: [f64; 6]) {
        match &self.design {
            Design::Fir(_) => self.state.iter_mut().for_each(|s| *s = x),
            Design::Iir(sections) => {
                // A section in transposed direct form II at rest with input v has output
                // G·v (G its DC gain) and states s2 = (b2 − a2·G)·v, s1 = (b1 − a1·G)·v + s2;
                // its output is the next section's input.
                let mut v = x;
                for (q, st) in sections.iter().zip(self.state.chunks_exact_mut(2)) {
                    let g = (q.b[0] + q.b[1] + q.b[2]) / (1.0 + q.a[0] + q.a[1]);
                    for (i, vi) in v.iter_mut().enumerate() {
                        st[1][i] = (q.b[2] - q.a[1] * g) * *vi;
                        st[0][i] = (q.b[1] - q.a[0] * g) * *vi + st[1][i];
                        *vi *= g;
                    }
                }
            }
        }
    }

    /// Feeds one sample; the output when `emit` (FIR outputs are only computed then).
    fn push(&mut self, x: [f64; 6], emit: bool) -> Option<[f64; 6]> {
        match &self.design {
            Design::Fir(h) => {
                let n = h.len();
                self.head = if self.head == 0 { n - 1 } else { self.head - 1 };
                self.state[self.head] = x;
                if !emit {
                    return None;
                }
                let mut y = [0.0; 6];
                for (k, c) in h.iter().enumerate() {
                    let s = &self.state[(self.head + k) % n];
                    for i in 0..6 {
                        y[i] += c * s[i];
                    }
                }
                Some(y)
            }
            Design::Iir(sections) => {
                // Transposed direct form II, section by section.
                let mut v = x;
                for (q, st) in sections.iter().zip(self.state.chunks_exact_mut(2)) {
                    let (first, second) = st.split_at_mut(1);
                    for ((x, s1), s2) in v.iter_mut().zip(&mut first[0]).zip(&mut second[0]) {
                        let y = q.b[0] * *x + *s1;
                        *s1 = q.b[1] * *x - q.a[0] * y + *s2;
                        *s2 = q.b[2] * *x - q.a[1] * y;
                        *x = y;
                    }
                }
                emit.then_some(v)
            }
        }
    }
}

impl Filter {
    /// The filter of `spec`, giving the internal samples `read` names.
    pub fn new(spec: &FilterSpec, read: ReadRatio) -> Filter {
        let fs = spec.internal_rate_hz;
        Filter {
            gyro: Bank::new(&spec.kind, fs),
            accel: spec.accel.as_ref().map(|k| Bank::new(k, fs)),
            read,
            pushed: 0,
            given: 0,
            next: read.index(1),
        }
    }

    /// Sets the state to the steady state of a constant input `x`, as if the filter had run on
    /// it for ever: a unit's filter runs from power-on, so its first outputs carry no start-up
    /// transient. Every kind has unit DC gain, so the next output of a constant `x` is `x`.
    pub fn prime(&mut self, x: [f64; 6]) {
        self.gyro.prime(x);
        if let Some(a) = &mut self.accel {
            a.prime(x);
        }
    }

    /// Feeds one internal sample; returns the filtered output when an output reads this sample.
    /// FIR outputs are only computed when read.
    pub fn push(&mut self, x: [f64; 6]) -> Option<[f64; 6]> {
        self.pushed += 1;
        let emit = self.pushed == self.next;
        if emit {
            self.given += 1;
            self.next = self.read.index(self.given + 1);
        }
        let g = self.gyro.push(x, emit);
        // Per-sensor filters run both designs over all six channels (the cost of the rare
        // case, keeping the common one a single pass) and keep each sensor's half.
        match &mut self.accel {
            Some(a) => g
                .zip(a.push(x, emit))
                .map(|(g, a)| [g[0], g[1], g[2], a[3], a[4], a[5]]),
            None => g,
        }
    }
}

/// Reads `[output_filter]`: `internal_rate_hz`, `kind` and the kind's keys (`taps`; `order`
/// and `taps`; `coefficients`; `order` and `cutoff`), and an optional `accel` table with the
/// accelerometers' own `kind` and keys. Errors name the key under the table.
pub fn from_toml(t: &toml::Table) -> Result<FilterSpec, (String, String)> {
    let err = |k: &str, m: &str| (k.to_string(), m.to_string());
    let number = |k: &str| -> Result<Option<f64>, (String, String)> {
        match t.get(k) {
            None => Ok(None),
            Some(v) => v
                .as_float()
                .or(v.as_integer().map(|i| i as f64))
                .filter(|x| x.is_finite())
                .map(Some)
                .ok_or_else(|| err(k, "expected a number")),
        }
    };
    let internal_rate_hz = number("internal_rate_hz")?
        .filter(|r| *r > 0.0 && *r <= crate::units::bounds::MAX_RATE_HZ)
        .ok_or_else(|| {
            err(
                "internal_rate_hz",
                &format!(
                    "expected a number in (0, {}] (Hz)",
                    crate::units::bounds::compact(crate::units::bounds::MAX_RATE_HZ)
                ),
            )
        })?;
    let kind = kind_from_toml(t, &["internal_rate_hz", "accel"])?;
    let accel = match t.get("accel") {
        None => None,
        Some(toml::Value::Table(a)) => {
            Some(kind_from_toml(a, &[]).map_err(|(k, m)| (format!("accel.{k}"), m))?)
        }
        Some(_) => {
            return Err(err(
                "accel",
                "expected a table (the accelerometers' filter)",
            ));
        }
    };
    let spec = FilterSpec {
        internal_rate_hz,
        kind,
        accel,
    };
    // The rate-independent checks (the output rate is checked when the chain is built).
    spec.kind.check(internal_rate_hz).map_err(|m| err("", &m))?;
    if let Some(a) = &spec.accel {
        a.check(internal_rate_hz).map_err(|m| err("accel", &m))?;
    }
    Ok(spec)
}

/// A filter's `kind` and that kind's keys, with `other` keys of the enclosing table allowed.
fn kind_from_toml(t: &toml::Table, other: &[&str]) -> Result<FilterKind, (String, String)> {
    let err = |k: &str, m: &str| (k.to_string(), m.to_string());
    let count = |k: &str| -> Result<usize, (String, String)> {
        match t.get(k).map(|v| v.as_integer()) {
            Some(Some(i)) if i > 0 => Ok(i as usize),
            Some(_) => Err(err(k, "expected a positive integer")),
            None => Err(err(k, "missing")),
        }
    };
    let kind_name = t.get("kind").and_then(|v| v.as_str()).ok_or_else(|| {
        err(
            "kind",
            "expected `moving_average`, `cic`, `fir` or `butterworth`",
        )
    })?;
    let allowed: &[&str] = match kind_name {
        "moving_average" => &["taps"],
        "cic" => &["order", "taps"],
        "fir" => &["coefficients"],
        "butterworth" => &["order", "cutoff"],
        _ => {
            return Err(err(
                "kind",
                "expected `moving_average`, `cic`, `fir` or `butterworth`",
            ));
        }
    };
    for k in t.keys() {
        if k != "kind" && !other.contains(&k.as_str()) && !allowed.contains(&k.as_str()) {
            return Err(err(
                k,
                &format!(
                    "unknown key for kind `{kind_name}` (expected {})",
                    allowed.join(", ")
                ),
            ));
        }
    }
    Ok(match kind_name {
        "moving_average" => FilterKind::MovingAverage {
            taps: count("taps")?,
        },
        "cic" => FilterKind::Cic {
            order: count("order")?,
            taps: count("taps")?,
        },
        "fir" => {
            let a = t
                .get("coefficients")
                .and_then(|v| v.as_array())
                .ok_or_else(|| err("coefficients", "expected a list of numbers"))?;
            let coefficients = a
                .iter()
                .map(|v| v.as_float().or(v.as_integer().map(|i| i as f64)))
                .collect::<Option<Vec<f64>>>()
                .filter(|c| c.iter().all(|x| x.is_finite()))
                .ok_or_else(|| err("coefficients", "expected finite numbers"))?;
            FilterKind::Fir { coefficients }
        }
        _ => {
            let s = t
                .get("cutoff")
                .and_then(|v| v.as_str())
                .ok_or_else(|| err("cutoff", "expected a string \"value Hz\""))?;
            let (cutoff_hz, _) = crate::units::parse(s, crate::units::Kind::Frequency)
                .map_err(|e| err("cutoff", &e.to_string()))?;
            FilterKind::Butterworth {
                order: count("order")?,
                cutoff_hz,
            }
        }
    })
}
