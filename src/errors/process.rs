//! The random processes of the error model, each advancing once per output record on its own
//! named stream.

use crate::rng::NormalStream;

/// First-order Gauss–Markov b' = −b/τ + w, discretised exactly for any Δt/τ:
/// b⁺ = e^{−Δt/τ} b + σ√(1 − e^{−2Δt/τ}) n, started from its stationary law b₀ ~ N(0, σ²).
#[derive(Clone, Debug)]
pub struct GaussMarkov {
    phi: f64,
    q: f64,
    /// The step Δt that `phi` and `q` are for, and σ, τ to form them for another step.
    dt: f64,
    sigma: f64,
    tau: f64,
    state: f64,
    rng: NormalStream,
}

impl GaussMarkov {
    /// Stationary σ, correlation time τ, step Δt, and the process's stream.
    pub fn new(sigma: f64, tau: f64, dt: f64, mut rng: NormalStream) -> GaussMarkov {
        let (phi, q) = GaussMarkov::transition(sigma, tau, dt);
        let state = sigma * rng.draw();
        GaussMarkov {
            phi,
            q,
            dt,
            sigma,
            tau,
            state,
            rng,
        }
    }
    /// The exact one-step factors over `dt`: e^{−Δt/τ} and the innovation's σ.
    fn transition(sigma: f64, tau: f64, dt: f64) -> (f64, f64) {
        // 1 − e^{−2x} without cancellation for small x.
        let q = sigma * (-(-2.0 * dt / tau).exp_m1()).sqrt();
        ((-dt / tau).exp(), q)
    }
    /// Advances one step and returns the new state.
    #[inline]
    pub fn step(&mut self) -> f64 {
        self.state = self.phi * self.state + self.q * self.rng.draw();
        self.state
    }
    /// Advances over `dt` (an externally triggered unit's own interval) with the exact
    /// discretisation for that step; the step given at construction costs no `exp`.
    #[inline]
    pub fn step_over(&mut self, dt: f64) -> f64 {
        if dt == self.dt {
            return self.step();
        }
        let (phi, q) = GaussMarkov::transition(self.sigma, self.tau, dt);
        self.state = phi * self.state + q * self.rng.draw();
        self.state
    }
    /// The current state.
    pub fn value(&self) -> f64 {
        self.state
    }
}

/// Random walk b⁺ = b + K√Δt n from b₀ = 0.
#[derive(Clone, Debug)]
pub struct RandomWalk {
    step_sigma: f64,
    /// Density K (unit/√s) and the step `step_sigma` is for.
    k: f64,
    dt: f64,
    state: f64,
    rng: NormalStream,
}

impl RandomWalk {
    /// Density K (unit/√s), step Δt.
    pub fn new(k: f64, dt: f64, rng: NormalStream) -> RandomWalk {
        RandomWalk {
            step_sigma: k * dt.sqrt(),
            k,
            dt,
            state: 0.0,
            rng,
        }
    }
    /// Advances one step and returns the new state.
    #[inline]
    pub fn step(&mut self) -> f64 {
        self.state += self.step_sigma * self.rng.draw();
        self.state
    }
    /// Advances over `dt` (an externally triggered unit's own interval): a step of σ K√Δt.
    #[inline]
    pub fn step_over(&mut self, dt: f64) -> f64 {
        let s = if dt == self.dt {
            self.step_sigma
        } else {
            self.k * dt.sqrt()
        };
        self.state += s * self.rng.draw();
        self.state
    }
}

/// Bias instability as a flicker-like process: a bank of Gauss–Markov processes with
/// log-spaced correlation times, two per decade, each of variance B² ln r / π, whose summed
/// one-sided PSD approximates B²/(π f) — the IEEE 952 flicker law whose Allan deviation is
/// the flat floor 0.664·B — over the frequencies that set the ADEV in [τ_lo, τ_hi].
///
/// Speed: a component with correlation time τ_c ≫ Δt is advanced on its own coarser grid of
/// step M·Δt ≤ τ_c/[`FLICKER_STEPS_PER_TAU`] (exact discretisation at that step) and held in
/// between; what the hold changes lies far above the component's bandwidth 1/(2πτ_c), where
/// the faster components and white noise dominate. Periods are powers of two sorted
/// ascending, so a sample that is not due for one component is not due for any slower one:
/// the bank costs about two normal draws per sample instead of one per component.
#[derive(Clone, Debug)]
pub struct Flicker {
    bank: Vec<HeldGm>,
    sum: f64,
    k: u64,
    /// Time since the start (s), summed over the samples' intervals.
    t: f64,
    /// The nominal sample step (s), and whether a sample of another interval came: from then
    /// on the components step over the elapsed time rather than their fixed period.
    dt: f64,
    irregular: bool,
}

#[derive(Clone, Debug)]
struct HeldGm {
    gm: GaussMarkov,
    /// Update period in samples, a power of two.
    period: u64,
    /// [`Flicker::t`] at the component's last update: an irregular unit steps it over the
    /// time actually elapsed since.
    last: f64,
}

/// Correlation-time spacing of the bank (two per decade).
pub const FLICKER_RATIO: f64 = 3.162_277_660_168_379_5;

/// Updates per correlation time of a held component.
pub const FLICKER_STEPS_PER_TAU: f64 = 16.0;

impl Flicker {
    /// Floor coefficient B, band [τ_lo, τ_hi] (s), step Δt; `stream(j)` gives component j's stream.
    pub fn new(
        b: f64,
        band: (f64, f64),
        dt: f64,
        mut stream: impl FnMut(usize) -> NormalStream,
    ) -> Flicker {
        let bank: Vec<HeldGm> = flicker_bank(b, band, dt)
            .into_iter()
            .enumerate()
            .map(|(j, c)| HeldGm {
                gm: GaussMarkov::new(c.sigma, c.tau, c.period as f64 * dt, stream(j)),
                period: c.period,
                last: 0.0,
            })
            .collect();
        let sum = bank.iter().map(|c| c.gm.value()).sum();
        Flicker {
            bank,
            sum,
            k: 0,
            t: 0.0,
            dt,
            irregular: false,
        }
    }
    /// Advances one sample and returns the sum of the components.
    #[inline]
    pub fn step(&mut self) -> f64 {
        self.step_over(self.dt)
    }
    /// Advances one sample of interval `dt` (an externally triggered unit's own interval):
    /// each component due is stepped exactly over the time elapsed since its last update.
    /// The variance scaling of components faster than the sampling stays the nominal step's.
    #[inline]
    pub fn step_over(&mut self, dt: f64) -> f64 {
        self.k += 1;
        self.t += dt;
        self.irregular |= dt != self.dt;
        let nominal = !self.irregular;
        for c in self.bank.iter_mut() {
            if self.k & (c.period - 1) != 0 {
                break;
            }
            let old = c.gm.value();
            let new = if nominal {
                c.gm.step()
            } else {
                c.gm.step_over(self.t - c.last)
            };
            c.last = self.t;
            self.sum += new - old;
        }
        if self.k & 0xffff == 0 {
            // Re-sum now and then so the running sum's rounding cannot accumulate.
            self.sum = self.bank.iter().map(|c| c.gm.value()).sum();
        }
        self.sum
    }
    /// Number of Gauss–Markov components.
    pub fn len(&self) -> usize {
        self.bank.len()
    }
    /// Always false.
    pub fn is_empty(&self) -> bool {
        self.bank.is_empty()
    }
}

/// One Gauss–Markov component of the bias-instability bank.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlickerComponent {
    /// Stationary σ (already scaled for components faster than the sampling).
    pub sigma: f64,
    /// Correlation time (s).
    pub tau: f64,
    /// Update period in samples (a power of two); the value is held in between.
    pub period: u64,
}

/// The components [`Flicker::new`] builds for floor coefficient B, band [τ_lo, τ_hi] and
/// step Δt (also what the analysis uses to draw the bank's exact theoretical curves).
pub fn flicker_bank(b: f64, band: (f64, f64), dt: f64) -> Vec<FlickerComponent> {
    let ln_r = FLICKER_RATIO.ln();
    let sigma = b * (ln_r / std::f64::consts::PI).sqrt();
    // ADEV at τ is mostly set by frequencies near 1/(2τ); a GM of correlation time τ_c
    // turns from flat to 1/f² at 1/(2πτ_c). Cover τ_c from τ_lo/π to τ_hi (one extra step
    // each side keeps the band edges flat).
    let lo = band.0 / std::f64::consts::PI / FLICKER_RATIO;
    let hi = band.1 * FLICKER_RATIO;
    let n = ((hi / lo).ln() / ln_r).ceil().max(1.0) as usize + 1;
    (0..n)
        .map(|j| {
            let tau = lo * FLICKER_RATIO.powi(j as i32);
            let steps = (tau / (FLICKER_STEPS_PER_TAU * dt)).max(1.0);
            let period = 1u64 << (steps.log2().floor() as u32).min(40);
            // A component faster than the sampling would alias its full variance into
            // white noise; scale its variance by the interval-mean factor
            // g(x) = 2(x − 1 + e^{−x})/x², x = Δt/τ_c, which keeps its low-frequency PSD
            // level 4σ²τ_c (g → 1 for slow components).
            let x = dt / tau;
            let g = if x < 1e-4 {
                1.0 - x / 3.0
            } else {
                2.0 * (x + (-x).exp_m1()) / (x * x)
            };
            FlickerComponent {
                sigma: sigma * g.sqrt(),
                tau,
                period,
            }
        })
        .collect()
}

/// How values are quantized to the output LSB.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum QuantMode {
    /// The paper's eq. 9–10: integer part (toward zero); biased by up to one LSB.
    Truncate,
    /// Nearest LSB per sample.
    Round,
    /// Pulse accumulation: the residual is carried, so the running sum of outputs stays within
    /// half an LSB of the running sum of inputs.
    Carry,
}

/// Quantizer of one axis.
#[derive(Clone, Debug)]
pub struct Quantizer {
    q: f64,
    inv_q: f64,
    mode: QuantMode,
    residual: f64,
}

impl Quantizer {
    /// Step q > 0 and mode.
    pub fn new(q: f64, mode: QuantMode) -> Quantizer {
        Quantizer {
            q,
            inv_q: 1.0 / q,
            mode,
            residual: 0.0,
        }
    }
    /// Quantizes x (a zero result is +0, never −0).
    #[inline]
    pub fn apply(&mut self, x: f64) -> f64 {
        0.0 + match self.mode {
            QuantMode::Truncate => (x * self.inv_q).trunc() * self.q,
            QuantMode::Round => round(x * self.inv_q) * self.q,
            QuantMode::Carry => {
                let total = x + self.residual;
                let out = round(total * self.inv_q) * self.q;
                self.residual = total - out;
                out
            }
        }
    }
}

/// Round half to even without a libm call (baseline x86-64 has no rounding instruction):
/// adding and subtracting 1.5·2⁵² leaves the nearest integer for |x| < 2⁵¹.
#[inline]
pub(crate) fn round(x: f64) -> f64 {
    const MAGIC: f64 = 6_755_399_441_055_744.0;
    if x.abs() < 2_251_799_813_685_248.0 {
        (x + MAGIC) - MAGIC
    } else {
        x.round()
    }
}
