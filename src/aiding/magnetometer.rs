//! Magnetometer: the Earth's main field as a centred dipole (the degree-1 terms of the IGRF),
//! seen in the body axes, through hard- and soft-iron distortion and white noise.
//!
//! With the degree-1 Gauss coefficients g = (g₁¹, h₁¹, g₁⁰) arranged along ECEF x, y, z, the
//! potential is V = a³ (g·r)/r³ and the field B = −∇V = (a/r)³ [3 (g·r̂) r̂ − g], a the
//! reference radius 6 371.2 km (IGRF; Alken et al., "International Geomagnetic Reference Field:
//! the thirteenth generation", Earth Planets Space 73, 49, 2021, table of coefficients).
//! The measurement is m = S B^b + b_hard + n. Instead of the dipole, a tabulated field
//! ([`super::field_table`]) may give B^n.

use std::path::PathBuf;
use std::sync::Arc;

use serde::Deserialize;

use super::field_table::{FieldTable, OutsideTable};
use crate::earth::Geodetic;
use crate::math::{Mat3, Quat, QuatExt, Vec3};
use crate::rng::NormalStream;

/// IGRF reference radius a (m).
pub const IGRF_RADIUS_M: f64 = 6_371_200.0;

/// IGRF-13 degree-1 coefficients for epoch 2020.0, (g₁⁰, g₁¹, h₁¹) in nT.
pub const IGRF13_2020_DIPOLE_NT: [f64; 3] = [-29_404.8, -1_450.9, 4_652.5];

/// Magnetometer settings: the scene file's `[magnetometer]` table (every key optional).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MagConfig {
    /// Samples per second, in (0, 1000].
    pub rate_hz: f64,
    /// Dipole coefficients (g₁⁰, g₁¹, h₁¹) (nT).
    pub dipole_nt: [f64; 3],
    /// A field table file (format in [`super::field_table`]) used instead of the dipole;
    /// relative to the scene file.
    pub field_table: Option<PathBuf>,
    /// The table read from `field_table` (set by whoever reads the file).
    #[serde(skip)]
    pub table: Option<Arc<FieldTable>>,
    /// Hard-iron offset, body axes (T).
    pub hard_iron_t: [f64; 3],
    /// Soft-iron matrix S (identity: none).
    pub soft_iron: [[f64; 3]; 3],
    /// White noise σ per axis and sample (T).
    pub noise_t: f64,
}

impl Default for MagConfig {
    /// The IGRF-13 2020 dipole at 10 Hz, no distortion, no noise.
    fn default() -> MagConfig {
        MagConfig {
            rate_hz: 10.0,
            dipole_nt: IGRF13_2020_DIPOLE_NT,
            field_table: None,
            table: None,
            hard_iron_t: [0.0; 3],
            soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            noise_t: 0.0,
        }
    }
}

impl MagConfig {
    /// Checks every value; the error names the `[magnetometer]` key.
    pub fn validate(&self) -> Result<(), super::gnss::ConfigError> {
        let c = super::gnss::Checks::new("magnetometer");
        c.rate("rate_hz", self.rate_hz)?;
        c.finite3("dipole_nt", &self.dipole_nt)?;
        c.finite3("hard_iron_t", &self.hard_iron_t)?;
        let det = Mat3::from_row_slice(self.soft_iron.as_flattened()).determinant();
        c.that(det.is_finite() && det.abs() > 1e-9, "soft_iron", || {
            format!("{:?} must be finite and invertible", self.soft_iron)
        })?;
        c.non_negative("noise_t", self.noise_t)
    }
}

/// The dipole field (T) in ECEF at ECEF position `r` (m) for coefficients `dipole_nt`.
pub fn dipole_field_e(dipole_nt: [f64; 3], r: Vec3) -> Vec3 {
    let [g10, g11, h11] = dipole_nt;
    let g = Vec3::new(g11, h11, g10) * 1e-9;
    let rn = r.norm();
    let u = r * (1.0 / rn);
    let k = (IGRF_RADIUS_M / rn).powi(3);
    (u * (3.0 * g.dot(&u)) - g) * k
}

/// The dipole field (T) in local NED at `pos`.
pub fn dipole_field_n(dipole_nt: [f64; 3], pos: &Geodetic) -> Vec3 {
    pos.c_n_e()
        .tr_mul(&(dipole_field_e(dipole_nt, pos.to_ecef())))
}

/// A magnetometer with its own noise streams.
#[derive(Clone, Debug)]
pub struct Magnetometer {
    cfg: MagConfig,
    noise: [NormalStream; 3],
}

impl Magnetometer {
    /// A magnetometer with `cfg`, noise streams of master seed `seed`.
    pub fn new(cfg: MagConfig, seed: u64) -> Magnetometer {
        Magnetometer {
            noise: std::array::from_fn(|i| {
                NormalStream::new(seed, &format!("mag/{}/noise", ["x", "y", "z"][i]))
            }),
            cfg,
        }
    }

    /// The Earth's field (T) in NED at `pos`: the table's, else the dipole's.
    pub fn field_n(&self, pos: &Geodetic) -> Result<Vec3, OutsideTable> {
        match &self.cfg.table {
            Some(t) => t.field_n(
                pos.sin_lat.atan2(pos.cos_lat),
                pos.sin_lon.atan2(pos.cos_lon),
            ),
            None => Ok(dipole_field_n(self.cfg.dipole_nt, pos)),
        }
    }

    /// The true body-axis field (T) at `pos` with attitude C_b^n = `q_b_n`.
    pub fn true_field_b(&self, pos: &Geodetic, q_b_n: Quat) -> Result<Vec3, OutsideTable> {
        Ok(q_b_n.rotate_inv(self.field_n(pos)?))
    }

    /// The measurement (T) of true body field `b`: S b + b_hard + noise (draws the noise).
    pub fn measure(&mut self, b: Vec3) -> Vec3 {
        let b = Mat3::from_row_slice(self.cfg.soft_iron.as_flattened()) * b;
        let s = self.cfg.noise_t;
        let n = Vec3::from(std::array::from_fn(|i| {
            if s > 0.0 {
                s * self.noise[i].draw()
            } else {
                0.0
            }
        }));
        b + Vec3::from(self.cfg.hard_iron_t) + n
    }

    /// The next measurement (T) at `pos` with attitude `q_b_n`: S B^b + b_hard + noise.
    pub fn sample(&mut self, pos: &Geodetic, q_b_n: Quat) -> Result<Vec3, OutsideTable> {
        let b = self.true_field_b(pos, q_b_n)?;
        Ok(self.measure(b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::earth;
    use crate::math::quat_from_euler;

    const AXIAL: [f64; 3] = [-30_000.0, 0.0, 0.0];

    /// An axial dipole on the equator points north with |g₁⁰|(a/r)³; at the pole it points
    /// down with twice that; at geocentric latitude ψ it dips by tan I = 2 tan ψ.
    #[test]
    fn axial_dipole_closed_forms() {
        let eq = Geodetic::from_radians(0.0, 0.7, 0.0);
        let k = (IGRF_RADIUS_M / earth::A).powi(3) * 30_000e-9;
        let b = dipole_field_n(AXIAL, &eq);
        assert!((b - Vec3::new(k, 0.0, 0.0)).amax() < 1e-20, "{b:?}");
        let pole = Geodetic::from_radians(std::f64::consts::FRAC_PI_2, 0.0, 0.0);
        let k = (IGRF_RADIUS_M / earth::B).powi(3) * 30_000e-9;
        let b = dipole_field_n(AXIAL, &pole);
        assert!((b - Vec3::new(0.0, 0.0, 2.0 * k)).amax() < 1e-19, "{b:?}");
        // Geocentric latitude 45°: in the geocentric (radial) frame tan I = 2.
        let r = Vec3::new(1.0, 0.0, 1.0) * (7.0e6 / 2f64.sqrt());
        let be = dipole_field_e(AXIAL, r);
        let up = r * (1.0 / r.norm());
        let north = Vec3::new(-1.0, 0.0, 1.0) * (1.0 / 2f64.sqrt());
        let ratio = -be.dot(&up) / be.dot(&north);
        assert!((ratio - 2.0).abs() < 1e-14, "{ratio}");
    }

    /// Turned to face east on the equator, body y points south: B^b = [0, −B_N, B_D]; hard and
    /// soft iron apply as S B^b + b exactly.
    #[test]
    fn body_axes_and_iron() {
        let pos = Geodetic::from_radians(0.0, 0.0, 100.0);
        let bn = dipole_field_n(AXIAL, &pos);
        let cfg = MagConfig {
            dipole_nt: AXIAL,
            hard_iron_t: [1e-6, -2e-6, 3e-6],
            soft_iron: [[1.1, 0.02, 0.0], [0.02, 0.9, 0.0], [0.0, 0.0, 1.0]],
            ..MagConfig::default()
        };
        let mut m = Magnetometer::new(cfg, 1);
        let q = quat_from_euler(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let bb = m.true_field_b(&pos, q).unwrap();
        assert!((bb - Vec3::new(0.0, -bn.x, bn.z)).amax() < 1e-20, "{bb:?}");
        let s = m.sample(&pos, q).unwrap();
        let expected = Vec3::new(
            1.1 * bb.x + 0.02 * bb.y + 1e-6,
            0.02 * bb.x + 0.9 * bb.y - 2e-6,
            bb.z + 3e-6,
        );
        assert!((s - expected).amax() < 1e-20, "{s:?}");
    }

    /// The IGRF-13 2020 dipole at 41° N 2° E is about 45 µT, dipping down by 50–60°.
    #[test]
    fn igrf_dipole_magnitude_is_earthlike() {
        let b = dipole_field_n(
            IGRF13_2020_DIPOLE_NT,
            &Geodetic::from_radians(41f64.to_radians(), 2f64.to_radians(), 0.0),
        );
        let dip = b.z.atan2(b.x.hypot(b.y)).to_degrees();
        assert!(
            (35e-6..55e-6).contains(&b.norm()) && (50.0..65.0).contains(&dip),
            "{b:?} {dip}"
        );
    }
}
