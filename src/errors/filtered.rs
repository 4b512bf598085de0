//! The error chain of a unit with an output filter (`[output_filter]`): records come in at the
//! unit's internal rate; every stage but quantization (and with it saturation) runs there, so
//! the noise and the vibration are generated at the internal rate; the output filter then
//! low-passes and decimates them to the output rate — a tone above the output Nyquist frequency
//! aliases, attenuated by the filter's response at its own frequency, as in the real unit —
//! and the output LSB and range apply last, at the output rate.

use super::chain::ErrorChain;
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
}

impl FilteredChain {
    /// The chain of `model` (which must carry an output filter) for output records at
    /// `output_rate_hz`; its input records are at the filter's internal rate.
    pub fn new(model: &ImuModel, output_rate_hz: f64, seed: u64) -> Result<FilteredChain, String> {
        let spec = model
            .output_filter
            .clone()
            .ok_or("the template has no [output_filter]")?;
        let decimation = spec.check(output_rate_hz)?;
        let inner_model = FilteredChain::inner_model(model);
        let mut outer_model = model.clone();
        let interface = |t: &TriadModel| TriadModel {
            quantization: t.quantization,
            range: t.range,
            ..TriadModel::default()
        };
        outer_model.gyro = interface(&model.gyro);
        outer_model.accel = interface(&model.accel);
        outer_model.output_filter = None;
        Ok(FilteredChain {
            inner: ErrorChain::new(&inner_model, spec.internal_rate_hz, seed),
            filter: Filter::new(&spec, decimation),
            outer: ErrorChain::new(&outer_model, output_rate_hz, seed),
            spec,
            dt_out: 1.0 / output_rate_hz,
            flags: 0,
            buf: Vec::new(),
            carried: Vec::new(),
            primed: false,
        })
    }

    /// The model of the internal-rate chain: `model` without its quantization, range and
    /// filter (those act at the output). To configure that chain, build it from this model at
    /// the internal rate and hand it to [`FilteredChain::map_inner`].
    pub fn inner_model(model: &ImuModel) -> ImuModel {
        let mut inner = model.clone();
        for t in [&mut inner.gyro, &mut inner.accel] {
            t.quantization = None;
            t.range = None;
        }
        inner.output_filter = None;
        inner
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

    /// The filter's DC group delay (s): an output sample's value is the true signal of that
    /// long before the end of its last internal interval (see `docs/fidelity.md`).
    pub fn latency_s(&self) -> f64 {
        self.spec.latency_s()
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
        if let Some(r) = self.buf.first().filter(|_| !self.primed) {
            let (g, a) = (r.gyro, r.accel);
            self.filter.prime([g[0], g[1], g[2], a[0], a[1], a[2]]);
            self.primed = true;
        }
        for r in &self.buf {
            self.flags |= r.flags;
            let (g, a) = (r.gyro, r.accel);
            if let Some(y) = self.filter.push([g[0], g[1], g[2], a[0], a[1], a[2]]) {
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
    }
}
