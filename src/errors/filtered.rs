//! The error chain of a unit with an output filter (`[output_filter]`): records come in at the
//! unit's internal rate; every stage but quantization (and with it saturation) runs there, so
//! the noise and the vibration are generated at the internal rate; the output filter then
//! low-passes and decimates them to the output rate — a tone above the output Nyquist frequency
//! aliases, attenuated by the filter's response at its own frequency, as in the real unit —
//! and the output LSB and range apply last, at the output rate.
//!
//! The injected errors (`--truth-errors`) of such a unit: the filter is linear, so the output
//! is the filter of the error-free internal signal plus the filter of each stage kind's
//! injected error, each run through its own copy of the filter (same coefficients, same
//! priming, same decimation phase); quantization and saturation, applied to the filter's
//! output, stay their own stage. The components then add up to the output minus the
//! filtered error-free signal.

use super::chain::{Components, ErrorChain};
use super::model::{ImuModel, TriadModel};
use super::output_filter::{Filter, FilterSpec};
use crate::generator::RotationTerms;
use crate::math::Vec3;
use crate::record::Record;

/// An [`ErrorChain`] at the internal rate, the output filter, and the output quantization.
#[derive(Clone, Debug)]
pub struct FilteredChain {
    inner: ErrorChain,
    filter: Filter,
    outer: ErrorChain,
    spec: FilterSpec,
    dt_out: f64,
    flags: u8,
    buf: Vec<Record>,
    carried: Vec<u8>,
    primed: bool,
    /// The per-kind filters and the output records' components, only when they are asked for
    /// ([`FilteredChain::with_components`]).
    split: Option<Box<Split>>,
}

/// One copy of the output filter per stage kind, and the components of the last output.
#[derive(Clone, Debug)]
struct Split {
    filters: Vec<Filter>,
    out: Vec<Components>,
}

/// Gyro and accelerometer as the filter's six channels.
fn channels(g: crate::math::Vec3, a: crate::math::Vec3) -> [f64; 6] {
    [g[0], g[1], g[2], a[0], a[1], a[2]]
}

/// The seed of the output-rate chain: its post-filter noise must not replay the draws the
/// internal-rate chain's white noise makes from the same stream names.
fn outer_seed(seed: u64) -> u64 {
    crate::rng::splitmix64(seed ^ crate::rng::fnv1a64("post_filter"))
}

impl FilteredChain {
    /// The chain of `model` (which must carry an output filter) for output records at
    /// `output_rate_hz`; its input records are at the filter's internal rate.
    pub fn new(model: &ImuModel, output_rate_hz: f64, seed: u64) -> Result<FilteredChain, String> {
        let spec = model
            .output_filter
            .clone()
            .ok_or("the template has no [output_filter]")?;
        let read = spec.check(output_rate_hz)?;
        let inner_model = FilteredChain::inner_model(model);
        let mut outer_model = model.clone();
        // The output stage: the noise added after the filter (and an LSB's noise without the
        // LSB, `quantization_noise`), then the LSB and the range.
        let interface = |t: &TriadModel| TriadModel {
            noise: t.post_filter_noise,
            quantization_noise: t.quantization_noise,
            quantization: t.quantization,
            range: t.range,
            ..TriadModel::default()
        };
        outer_model.gyro = interface(&model.gyro);
        outer_model.accel = interface(&model.accel);
        outer_model.output_filter = None;
        Ok(FilteredChain {
            inner: ErrorChain::new(&inner_model, spec.internal_rate_hz, seed),
            filter: Filter::new(&spec, read),
            // Streams of their own: the inner chain's noise streams have the same names.
            outer: ErrorChain::new(&outer_model, output_rate_hz, outer_seed(seed)),
            spec,
            dt_out: 1.0 / output_rate_hz,
            flags: 0,
            buf: Vec::new(),
            carried: Vec::new(),
            primed: false,
            split: None,
        })
    }

    /// The model of the internal-rate chain: `model` without its quantization (and
    /// quantization noise), range and filter (those act at the output). To configure that chain, build it from this model at
    /// the internal rate and hand it to [`FilteredChain::map_inner`].
    pub fn inner_model(model: &ImuModel) -> ImuModel {
        let mut inner = model.clone();
        for t in [&mut inner.gyro, &mut inner.accel] {
            t.quantization = None;
            t.quantization_noise = [0.0; 3];
            t.range = None;
        }
        inner.output_filter = None;
        inner
    }

    /// Records, on each apply, the error every kind of stage injected into each output record
    /// ([`FilteredChain::components`]): the internal-rate errors through their own copies of
    /// the filter, plus the output quantization's. Must be set before the first apply (the
    /// copies start from the filter's state, which is then still unprimed).
    pub fn with_components(mut self) -> FilteredChain {
        debug_assert!(!self.primed, "components asked for after the first apply");
        self.inner = self.inner.with_components();
        self.outer = self.outer.with_components();
        self.split = Some(Box::new(Split {
            filters: vec![self.filter.clone(); super::StageKind::ALL.len()],
            out: Vec::new(),
        }));
        self
    }

    /// The injected errors of the output records of the last apply, in their order (empty
    /// unless asked for with [`FilteredChain::with_components`]).
    pub fn components(&self) -> &[Components] {
        self.split.as_ref().map_or(&[], |s| &s.out)
    }

    /// The injected errors of the last apply, to fold skipped samples into (`None` unless
    /// asked for).
    pub fn components_mut(&mut self) -> Option<&mut Vec<Components>> {
        self.split.as_mut().map(|s| &mut s.out)
    }

    /// Whether the internal-rate chain needs the motion's rotation terms (a lever arm).
    pub fn needs_rotation_terms(&self) -> bool {
        self.inner.needs_rotation_terms()
    }

    /// Lets the internal-rate chain be configured (vibration, temperature, mounting…).
    pub fn map_inner(mut self, f: impl FnOnce(ErrorChain) -> ErrorChain) -> FilteredChain {
        self.inner = f(self.inner);
        self
    }

    /// The filter's DC group delay (s) on the gyros (`accel` false) or the accelerometers: an
    /// output sample's value is the true signal of that long before the end of its last
    /// internal interval (see `docs/fidelity.md`).
    pub fn latency_s(&self, accel: bool) -> f64 {
        self.spec.sensor(accel).latency_s()
    }

    /// The filter spec.
    pub fn spec(&self) -> &FilterSpec {
        &self.spec
    }

    /// Corrupts internal-rate records and appends the output-rate records they complete to
    /// `out` (time tag: the end of the output interval; flags: any raised in the interval).
    pub fn apply(&mut self, input: &[Record], out: &mut Vec<Record>) {
        self.apply_with(input, None, out);
    }

    /// [`FilteredChain::apply`] with the internal records' rotation terms (see
    /// [`ErrorChain::apply_with`]). The filter starts primed with the first corrupted record,
    /// as a unit's filter has been running since power-on.
    pub fn apply_with(
        &mut self,
        input: &[Record],
        rotation: Option<&[RotationTerms]>,
        out: &mut Vec<Record>,
    ) {
        self.buf.clear();
        self.buf.extend_from_slice(input);
        self.inner.apply_with(&mut self.buf, rotation);
        let first = out.len();
        let comps = self.inner.components();
        let mut split = self.split.as_deref_mut();
        if let Some(s) = split.as_mut() {
            s.out.clear();
        }
        if let Some(r) = self.buf.first().filter(|_| !self.primed) {
            self.filter.prime(channels(r.gyro, r.accel));
            if let (Some(s), Some(c)) = (split.as_mut(), comps.first()) {
                for (f, [g, a]) in s.filters.iter_mut().zip(c.0) {
                    f.prime(channels(g, a));
                }
            }
            self.primed = true;
        }
        for (i, r) in self.buf.iter().enumerate() {
            self.flags |= r.flags;
            // The copies share the main filter's phase, so they emit on the same samples.
            if let Some(s) = split.as_mut() {
                let mut emitted = Components::default();
                let mut any = false;
                for ((f, [g, a]), e) in s.filters.iter_mut().zip(comps[i].0).zip(&mut emitted.0) {
                    if let Some(y) = f.push(channels(g, a)) {
                        *e = [Vec3::new(y[0], y[1], y[2]), Vec3::new(y[3], y[4], y[5])];
                        any = true;
                    }
                }
                if any {
                    s.out.push(emitted);
                }
            }
            if let Some(y) = self.filter.push(channels(r.gyro, r.accel)) {
                let gyro = Vec3::new(y[0], y[1], y[2]);
                let accel = Vec3::new(y[3], y[4], y[5]);
                out.push(Record {
                    t: r.t,
                    gyro,
                    accel,
                    dtheta: gyro * self.dt_out,
                    dv: accel * self.dt_out,
                    flags: std::mem::take(&mut self.flags),
                });
            }
        }
        // Quantization and saturation OR their flags into the ones carried over.
        self.carried.clear();
        self.carried.extend(out[first..].iter().map(|r| r.flags));
        self.outer.apply(&mut out[first..]);
        for (r, f) in out[first..].iter_mut().zip(&self.carried) {
            r.flags |= f;
        }
        if let Some(s) = split {
            // The output stages' own errors (quantization, saturation) at the output rate.
            for (c, o) in s.out.iter_mut().zip(self.outer.components()) {
                for (cg, og) in c.0.iter_mut().zip(o.0) {
                    cg[0] += og[0];
                    cg[1] += og[1];
                }
            }
        }
    }
}

impl FilteredChain {
    /// Corrupts records that are each the exact mean of the signal over an interval of `dt`
    /// s an external trigger closed, as the unit's filter works under external sync: a
    /// uniform averager over the interval between the edges (KVH's 1775 IMU technical
    /// manual), whose output is the interval mean of the internal samples. The internal-rate
    /// stages act over the whole interval (their white noise averaged over it has
    /// σ = N/√`dt`, their random processes step over `dt`: [`ErrorChain::apply_over`]), then
    /// the output LSB and range. The lowpass filter and its decimation are not run.
    pub fn apply_over(
        &mut self,
        records: &mut [Record],
        rotation: Option<&[RotationTerms]>,
        dt: f64,
    ) {
        self.inner.apply_over(records, rotation, dt);
        // Quantization and saturation OR their flags into the internal stages' ones.
        self.carried.clear();
        self.carried.extend(records.iter().map(|r| r.flags));
        self.outer.apply_over(records, None, dt);
        for (r, f) in records.iter_mut().zip(&self.carried) {
            r.flags |= f;
        }
        if let Some(s) = self.split.as_deref_mut() {
            s.out.clear();
            let (inner, outer) = (self.inner.components(), self.outer.components());
            for (i, o) in inner.iter().zip(outer) {
                let mut c = *i;
                for (cg, og) in c.0.iter_mut().zip(o.0) {
                    cg[0] += og[0];
                    cg[1] += og[1];
                }
                s.out.push(c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::errors::template::parse;

    /// Without `with_components` the chain holds no per-kind filter copies and returns no
    /// components (the injected errors cost nothing unless asked for); with it, one set of
    /// components per output record.
    #[test]
    fn components_only_when_asked() {
        let text = "name = \"f\"\n[gyro]\nnoise = \"1 deg/sqrt(h)\"\n\
                    [output_filter]\ninternal_rate_hz = 800\nkind = \"moving_average\"\ntaps = 4\n";
        let model = parse(text, std::path::Path::new("f.toml")).unwrap();
        let input: Vec<Record> = (0..40)
            .map(|k| Record {
                t: (k + 1) as f64 / 800.0,
                ..Record::default()
            })
            .collect();
        let mut plain = FilteredChain::new(&model, 200.0, 1).unwrap();
        assert!(plain.split.is_none());
        let mut out = Vec::new();
        plain.apply(&input, &mut out);
        assert_eq!(out.len(), 10);
        assert!(plain.components().is_empty() && plain.split.is_none());
        let mut asked = FilteredChain::new(&model, 200.0, 1)
            .unwrap()
            .with_components();
        let mut again = Vec::new();
        asked.apply(&input, &mut again);
        assert_eq!(asked.components().len(), 10);
        // The same records either way: capturing does not disturb the run.
        assert_eq!(out, again);
    }

    /// `post_filter_noise` is added after the filter: white at the output rate. With only it
    /// set (P) under a moving average of 8 taps read every 4th internal sample, the outputs have
    /// variance P²/Δt and no lag-one correlation; through the filter they would have
    /// 8/64·4 = 1/2 of that variance and a lag-one correlation of 1/2 (Σ h_i h_{i+4} over
    /// Σ h_i²). 3·2^16 samples pooled over the axes: the variance estimate's relative sd is
    /// √(2/n) = 0.32 %, the correlation's 1/√n = 0.0023; both are checked to 4σ.
    #[test]
    fn post_filter_noise_is_white_at_the_output_rate() {
        let text = "name = \"p\"\n[gyro]\npost_filter_noise = \"60 deg/sqrt(h)\"\n\
                    [output_filter]\ninternal_rate_hz = 800\nkind = \"moving_average\"\ntaps = 8\n";
        let model = parse(text, std::path::Path::new("p.toml")).unwrap();
        let n_out = 1usize << 16;
        let input: Vec<Record> = (0..4 * n_out)
            .map(|k| Record {
                t: (k + 1) as f64 / 800.0,
                ..Record::default()
            })
            .collect();
        let mut chain = FilteredChain::new(&model, 200.0, 7).unwrap();
        let mut out = Vec::new();
        chain.apply(&input, &mut out);
        assert_eq!(out.len(), n_out);
        let p = 1.0_f64.to_radians(); // 60 deg/√h = 1 deg/√s
        let want = p * p * 200.0;
        let (mut var, mut lag) = (0.0, 0.0);
        for axis in 0..3 {
            let x: Vec<f64> = out.iter().map(|r| r.gyro[axis]).collect();
            var += x.iter().map(|v| v * v).sum::<f64>();
            lag += x.windows(2).map(|w| w[0] * w[1]).sum::<f64>();
        }
        let n = (3 * n_out) as f64;
        let rho = lag / var;
        var /= n;
        let sd = (2.0 / n).sqrt();
        assert!(
            (var / want - 1.0).abs() < 4.0 * sd,
            "variance {var:e} vs {want:e}"
        );
        assert!(rho.abs() < 4.0 / n.sqrt(), "lag-one correlation {rho}");
    }
}
