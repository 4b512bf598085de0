//! Barometric altimeter: static pressure of the International Standard Atmosphere at the
//! vehicle's height, with white noise and a random-walk bias drift on the pressure, and the
//! pressure altitude a barometric altimeter reports from it.
//!
//! ISA as in the U.S. Standard Atmosphere 1976 (NOAA-S/T 76-1562), identical to ICAO / ISO 2533
//! below 20 km: troposphere T = T₀ − L·H, p = p₀ (T/T₀)^{g₀M/(R*L)}; from 11 km an isothermal
//! layer p = p₁₁ exp(−g₀M(H − 11 000)/(R*T₁₁)). H is geopotential height,
//! H = r₀h/(r₀ + h) with r₀ = 6 356 766 m. There is no geoid model: h is the ellipsoidal height.

use crate::rng::NormalStream;

/// Sea-level pressure p₀ (Pa).
pub const P0: f64 = 101_325.0;
/// Sea-level temperature T₀ (K).
pub const T0: f64 = 288.15;
/// Tropospheric lapse rate L (K/m).
pub const LAPSE: f64 = 0.0065;
/// Standard gravity g₀ (m/s²).
pub const G0: f64 = 9.806_65;
/// Molar mass of air M (kg/mol).
pub const MOLAR_MASS: f64 = 0.028_964_4;
/// Universal gas constant R* of the 1976 standard (J/(mol·K)).
pub const R_STAR: f64 = 8.314_32;
/// Earth radius of the geopotential conversion r₀ (m).
pub const R0: f64 = 6_356_766.0;
/// Geopotential height of the tropopause (m).
pub const H_TROPOPAUSE: f64 = 11_000.0;
/// Top of the model (geopotential m): the isothermal layer ends at 20 km.
pub const H_TOP: f64 = 20_000.0;

/// g₀M/(R*L), the troposphere's exponent.
fn exponent() -> f64 {
    G0 * MOLAR_MASS / (R_STAR * LAPSE)
}

/// Geopotential height (m) of geometric height `h` (m).
pub fn geopotential(h: f64) -> f64 {
    R0 * h / (R0 + h)
}

/// Geometric height (m) of geopotential height `hp` (m).
pub fn geometric(hp: f64) -> f64 {
    R0 * hp / (R0 - hp)
}

/// ISA static pressure (Pa) at geopotential height `hp` (m), for `hp` up to [`H_TOP`].
pub fn pressure(hp: f64) -> f64 {
    let t11 = T0 - LAPSE * H_TROPOPAUSE;
    if hp <= H_TROPOPAUSE {
        P0 * ((T0 - LAPSE * hp) / T0).powf(exponent())
    } else {
        let p11 = P0 * (t11 / T0).powf(exponent());
        p11 * (-G0 * MOLAR_MASS * (hp - H_TROPOPAUSE) / (R_STAR * t11)).exp()
    }
}

/// Pressure altitude (geopotential m) of static pressure `p` (Pa): the inverse of [`pressure`].
pub fn pressure_altitude(p: f64) -> f64 {
    let t11 = T0 - LAPSE * H_TROPOPAUSE;
    let p11 = P0 * (t11 / T0).powf(exponent());
    if p >= p11 {
        T0 / LAPSE * (1.0 - (p / P0).powf(1.0 / exponent()))
    } else {
        H_TROPOPAUSE - R_STAR * t11 / (G0 * MOLAR_MASS) * (p / p11).ln()
    }
}

/// Barometer settings: the scene file's `[baro]` table (every key optional).
#[derive(Clone, Debug, serde::Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct BaroConfig {
    /// Samples per second, in (0, 1000].
    pub rate_hz: f64,
    /// White pressure noise σ per sample (Pa).
    pub noise_pa: f64,
    /// Random-walk density of the pressure bias (Pa/√s).
    pub bias_rw_pa_sqrt_s: f64,
    /// Initial pressure bias (Pa).
    pub bias0_pa: f64,
}

impl Default for BaroConfig {
    /// 10 Hz, 1 Pa white noise (about 8 cm at sea level), no bias.
    fn default() -> BaroConfig {
        BaroConfig {
            rate_hz: 10.0,
            noise_pa: 1.0,
            bias_rw_pa_sqrt_s: 0.0,
            bias0_pa: 0.0,
        }
    }
}

impl BaroConfig {
    /// Checks every value; the error names the `[baro]` key.
    pub fn validate(&self) -> Result<(), super::gnss::ConfigError> {
        let c = super::gnss::Checks::new("baro");
        c.rate("rate_hz", self.rate_hz)?;
        c.non_negative("noise_pa", self.noise_pa)?;
        c.non_negative("bias_rw_pa_sqrt_s", self.bias_rw_pa_sqrt_s)?;
        // A bias beyond a tenth of the sea-level pressure is not a barometer's.
        let b = self.bias0_pa;
        c.that(b.is_finite() && b.abs() <= 0.1 * P0, "bias0_pa", || {
            format!("{b} is outside ±{} Pa", 0.1 * P0)
        })
    }
}

/// One barometer sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaroSample {
    /// True static pressure (Pa).
    pub true_pa: f64,
    /// Reported static pressure (Pa).
    pub pa: f64,
    /// Reported pressure altitude (geometric m).
    pub altitude_m: f64,
    /// The bias in this sample (Pa).
    pub bias_pa: f64,
}

/// A barometer sampled every `dt` seconds on its own random streams.
#[derive(Clone, Debug)]
pub struct Barometer {
    cfg: BaroConfig,
    step_sigma: f64,
    bias: f64,
    noise: NormalStream,
    walk: NormalStream,
}

impl Barometer {
    /// A barometer with `cfg`, sample interval `dt` (s), streams of master seed `seed`.
    pub fn new(cfg: BaroConfig, dt: f64, seed: u64) -> Barometer {
        Barometer {
            step_sigma: cfg.bias_rw_pa_sqrt_s * dt.sqrt(),
            bias: cfg.bias0_pa,
            noise: NormalStream::new(seed, "baro/noise"),
            walk: NormalStream::new(seed, "baro/bias"),
            cfg,
        }
    }

    /// The next sample at ellipsoidal height `h` (m); the bias walks after each sample.
    pub fn sample(&mut self, h: f64) -> BaroSample {
        let true_pa = pressure(geopotential(h));
        let pa = true_pa + self.bias + self.cfg.noise_pa * self.noise.draw();
        let s = BaroSample {
            true_pa,
            pa,
            altitude_m: geometric(pressure_altitude(pa)),
            bias_pa: self.bias,
        };
        self.bias += self.step_sigma * self.walk.draw();
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The layer-base pressures of the 1976 standard's table 4: 22 632.06 Pa at 11 km and
    /// 5 474.889 Pa at 20 km geopotential; p₀ at 0.
    #[test]
    fn isa_layer_bases() {
        assert_eq!(pressure(0.0), P0);
        assert!(
            (pressure(11_000.0) - 22_632.06).abs() < 0.01,
            "{}",
            pressure(11_000.0)
        );
        assert!(
            (pressure(20_000.0) - 5_474.889).abs() < 0.001,
            "{}",
            pressure(20_000.0)
        );
    }

    /// Pressure altitude inverts the pressure in both layers, to round-off.
    #[test]
    fn pressure_altitude_inverts_pressure() {
        for hp in [-400.0, 0.0, 1234.5, 10_999.0, 11_000.0, 11_001.0, 19_000.0] {
            let back = pressure_altitude(pressure(hp));
            assert!((back - hp).abs() < 1e-8, "{hp}: {back}");
        }
        for h in [0.0, 5000.0, 15_000.0] {
            assert!((geometric(geopotential(h)) - h).abs() < 1e-9);
        }
        // 10 km geometric is 15.7 m lower in geopotential (r₀h/(r₀+h)).
        assert!((geopotential(10_000.0) - 10_000.0 * R0 / (R0 + 10_000.0)).abs() < 1e-9);
    }

    /// Without noise the reported altitude is the height offset by the bias through the local
    /// pressure gradient; the bias walks with variance K²t: over 10 000 samples of 0.1 s the
    /// final bias of 400 independent barometers has variance K²·1000 s, within 4σ of the
    /// sample variance's relative scatter √(2/400) = 0.071.
    #[test]
    fn bias_and_drift() {
        let cfg = BaroConfig {
            noise_pa: 0.0,
            bias_rw_pa_sqrt_s: 0.0,
            bias0_pa: -12.0,
            ..BaroConfig::default()
        };
        let s = Barometer::new(cfg, 0.1, 1).sample(500.0);
        assert_eq!(s.pa, pressure(geopotential(500.0)) - 12.0);
        assert!(
            s.altitude_m > 500.0 && s.altitude_m < 502.0,
            "{}",
            s.altitude_m
        );
        let k = 0.5;
        let n = 400;
        let finals: Vec<f64> = (0..n)
            .map(|i| {
                let cfg = BaroConfig {
                    noise_pa: 0.0,
                    bias_rw_pa_sqrt_s: k,
                    bias0_pa: 0.0,
                    ..BaroConfig::default()
                };
                let mut b = Barometer::new(cfg, 0.1, i);
                (0..10_000).map(|_| b.sample(0.0).bias_pa).last().unwrap()
            })
            .collect();
        let var = finals.iter().map(|x| x * x).sum::<f64>() / n as f64;
        // The last sample carries 9 999 steps of the walk.
        let expected = k * k * 0.1 * 9_999.0;
        assert!(
            (var / expected - 1.0).abs() < 4.0 * (2.0 / n as f64).sqrt(),
            "{var} vs {expected}"
        );
    }
}
