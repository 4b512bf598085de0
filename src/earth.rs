//! WGS-84 Earth model: constants, radii of curvature, normal gravity, and the geodetic ↔ ECEF
//! conversions (NIMA TR8350.2, *Department of Defense World Geodetic System 1984*, ch. 3–4).
//! Pure math, no I/O.

#[cfg(test)]
use crate::math::QuatExt;
use crate::math::{Mat3, Quat, Vec3};

/// Semi-major axis a (m).
pub const A: f64 = 6_378_137.0;
/// Flattening f.
pub const F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared e² = f(2 − f).
pub const E2: f64 = F * (2.0 - F);
/// Semi-minor axis b = a(1 − f) (m).
pub const B: f64 = A * (1.0 - F);
/// Earth rotation rate ω_ie (rad/s).
pub const OMEGA_IE: f64 = 7.292_115e-5;
/// Geocentric gravitational constant GM (m³/s²).
pub const GM: f64 = 3.986_004_418e14;
/// Normal gravity at the equator γ_e (m/s²).
pub const GAMMA_E: f64 = 9.780_325_335_9;
/// Somigliana constant k = (b γ_p − a γ_e)/(a γ_e).
pub const SOMIGLIANA_K: f64 = 0.001_931_852_652_41;
/// m = ω² a² b / GM.
pub const M_RATIO: f64 = 0.003_449_786_506_84;

/// Meridian radius of curvature R_N = a(1−e²)/(1−e² sin²φ)^{3/2}, from sin φ.
#[inline]
pub fn radius_meridian(sin_lat: f64) -> f64 {
    let w = 1.0 - E2 * sin_lat * sin_lat;
    A * (1.0 - E2) / (w * w.sqrt())
}

/// Prime-vertical radius of curvature R_E = a/√(1−e² sin²φ), from sin φ.
#[inline]
pub fn radius_prime_vertical(sin_lat: f64) -> f64 {
    A / (1.0 - E2 * sin_lat * sin_lat).sqrt()
}

/// WGS-84 normal gravity magnitude γ(φ, h) (m/s²): Somigliana on the ellipsoid with the
/// second-order height correction γ = γ₀[1 − (2/a)(1 + f + m − 2f sin²φ)h + 3h²/a²].
#[inline]
pub fn normal_gravity(sin_lat: f64, h: f64) -> f64 {
    let s2 = sin_lat * sin_lat;
    normal_gravity_from(s2, 1.0 / (1.0 - E2 * s2).sqrt(), h)
}

/// [`normal_gravity`] from sin²φ and 1/√(1 − e² sin²φ), for callers that already hold them.
#[inline]
pub fn normal_gravity_from(sin2_lat: f64, inv_sqrt_w: f64, h: f64) -> f64 {
    let g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * sin2_lat) * inv_sqrt_w;
    g0 * (1.0 - (2.0 / A) * (1.0 + F + M_RATIO - 2.0 * F * sin2_lat) * h + (3.0 / (A * A)) * h * h)
}

/// The gradient of the gravitational acceleration (gravity without the Earth's centrifugal
/// acceleration) at geodetic latitude φ and height h, in the local NED axes (s⁻²): the
/// gravitation at a point displaced by δ (NED, m) is G + Γ δ to first order. Of the normal
/// gravity field this engine uses (magnitude γ(φ, h) along the ellipsoid's normal,
/// [`normal_gravity`]): a displacement north or east turns the normal by δ/(M + h) or
/// δ/(N + h), moving down changes γ by −∂γ/∂h, moving north by ∂γ/∂φ/(M + h); the centrifugal
/// part's gradient Ω² = [ω_ie×]², which the lever-arm kinematics carry through ω_ib, is added
/// back. A specific force at a lever arm r from a point differs by −Γ r besides its kinematic
/// terms (about 3·10⁻⁶ s⁻² vertically: 4.6·10⁻⁶ m/s² at 1.5 m).
pub fn gravitation_gradient_ned(sin_lat: f64, cos_lat: f64, h: f64) -> Mat3 {
    // γ = γ₀(s²)·H(s², h) of `normal_gravity_from`, differentiated in closed form
    // (s² = sin²φ, w = 1 − e²s²): ∂γ₀/∂s² = γ_e[k/√w + (1 + k s²)e²/(2w^{3/2})],
    // ∂H/∂s² = 4f h/a, ∂H/∂h = −(2/a)(1 + f + m − 2f s²) + 6h/a², ∂s²/∂φ = 2 sin φ cos φ.
    let s2 = sin_lat * sin_lat;
    let isw = 1.0 / (1.0 - E2 * s2).sqrt();
    let g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) * isw;
    let k_h = (2.0 / A) * (1.0 + F + M_RATIO - 2.0 * F * s2);
    let big_h = 1.0 - k_h * h + (3.0 / (A * A)) * h * h;
    let gamma = g0 * big_h;
    let dg_dh = g0 * (-k_h + (6.0 / (A * A)) * h);
    let dg0_ds2 =
        GAMMA_E * (SOMIGLIANA_K * isw + (1.0 + SOMIGLIANA_K * s2) * 0.5 * E2 * isw * isw * isw);
    let dg_dlat = (dg0_ds2 * big_h + g0 * (4.0 * F * h / A)) * 2.0 * sin_lat * cos_lat;
    let m = A * (1.0 - E2) * isw * isw * isw + h;
    let n = A * isw + h;
    let gravity = Mat3::new(
        -gamma / m,
        0.0,
        0.0,
        0.0,
        -gamma / n,
        0.0,
        dg_dlat / m,
        0.0,
        -dg_dh,
    );
    let w = omega_ie_n(sin_lat, cos_lat);
    gravity + w * w.transpose() - Mat3::identity() * w.norm_squared()
}

/// Earth rate in the local-level frame ω_ie^n = [ω cos φ, 0, −ω sin φ].
#[inline]
pub fn omega_ie_n(sin_lat: f64, cos_lat: f64) -> Vec3 {
    Vec3::new(OMEGA_IE * cos_lat, 0.0, -OMEGA_IE * sin_lat)
}

/// Transport rate ω_en^n = [v_E/(R_E+h), −v_N/(R_N+h), −v_E tan φ/(R_E+h)].
///
/// Singular at the poles only through v_E tan φ; an exactly zero v_E gives an exactly zero
/// third component (so a vehicle moving along a meridian through the pole stays finite).
#[inline]
pub fn omega_en_n(sin_lat: f64, cos_lat: f64, h: f64, v_n: Vec3) -> Vec3 {
    transport_rate(
        sin_lat,
        cos_lat,
        radius_meridian(sin_lat) + h,
        radius_prime_vertical(sin_lat) + h,
        v_n,
    )
}

/// [`omega_en_n`] with the radii R_N + h and R_E + h already known.
#[inline]
pub fn transport_rate(sin_lat: f64, cos_lat: f64, rn_h: f64, re_h: f64, v_n: Vec3) -> Vec3 {
    let inv_re_h = 1.0 / re_h;
    let east = v_n.y * inv_re_h;
    let z = if v_n.y == 0.0 {
        0.0
    } else {
        -east * sin_lat / cos_lat
    };
    Vec3::new(east, -v_n.x / rn_h, z)
}

/// A geodetic position held as the sines and cosines it is used through (pole-safe).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geodetic {
    /// sin φ.
    pub sin_lat: f64,
    /// cos φ (≥ 0 for ordinary latitudes; may be negative for an "extended" latitude past a pole).
    pub cos_lat: f64,
    /// sin λ.
    pub sin_lon: f64,
    /// cos λ.
    pub cos_lon: f64,
    /// Ellipsoidal height h (m).
    pub h: f64,
}

impl Geodetic {
    /// From latitude and longitude in radians and height in metres.
    pub fn from_radians(lat: f64, lon: f64, h: f64) -> Geodetic {
        let (sin_lat, cos_lat) = lat.sin_cos();
        let (sin_lon, cos_lon) = lon.sin_cos();
        Geodetic {
            sin_lat,
            cos_lat,
            sin_lon,
            cos_lon,
            h,
        }
    }
    /// Latitude in radians.
    pub fn lat(&self) -> f64 {
        self.sin_lat.atan2(self.cos_lat)
    }
    /// Longitude in radians, in (−π, π].
    pub fn lon(&self) -> f64 {
        self.sin_lon.atan2(self.cos_lon)
    }
    /// ECEF position r^e (m).
    pub fn to_ecef(&self) -> Vec3 {
        let n = radius_prime_vertical(self.sin_lat);
        let rho = (n + self.h) * self.cos_lat;
        Vec3::new(
            rho * self.cos_lon,
            rho * self.sin_lon,
            (n * (1.0 - E2) + self.h) * self.sin_lat,
        )
    }
    /// Unit vector of the local "up" (minus NED down) in ECEF.
    #[inline]
    pub fn up_e(&self) -> Vec3 {
        Vec3::new(
            self.cos_lat * self.cos_lon,
            self.cos_lat * self.sin_lon,
            self.sin_lat,
        )
    }
    /// C_n^e, the NED-to-ECEF direction cosine matrix (columns: north, east, down in ECEF).
    pub fn c_n_e(&self) -> Mat3 {
        let (sp, cp, sl, cl) = (self.sin_lat, self.cos_lat, self.sin_lon, self.cos_lon);
        #[rustfmt::skip]
        let c = Mat3::new(
            -sp * cl, -sl, -cp * cl,
            -sp * sl, cl, -cp * sl,
            cp, 0.0, -sp,
        );
        c
    }
    /// Quaternion of C_n^e.
    pub fn q_n_e(&self) -> Quat {
        // C_n^e = Rz(λ) · Ry(−φ − π/2); built from half-angle identities to stay exact at poles.
        let lat = self.lat();
        let lon = self.lon();
        let qz = {
            let (s, c) = (0.5 * lon).sin_cos();
            Quat::new(c, 0.0, 0.0, s)
        };
        let qy = {
            let (s, c) = (0.5 * (-lat - std::f64::consts::FRAC_PI_2)).sin_cos();
            Quat::new(c, 0.0, s, 0.0)
        };
        qz * qy
    }
}

/// ECEF position to geodetic, exact to round-off at any height above −a/2 and at the poles.
///
/// Bowring's 1976 formula as the first guess, then fixed-point refinement of (cos φ, sin φ)
/// written without dividing by the distance to the axis, so the poles need no special case.
/// Each step shrinks the error by ≈ e²; near the Earth one or two steps after Bowring reach
/// the f64 floor, higher up a few more.
pub fn ecef_to_geodetic(r: Vec3) -> Geodetic {
    let (x, y, z) = (r.x, r.y, r.z);
    let rho = (x * x + y * y).sqrt();
    let (sin_lon, cos_lon) = if rho > 0.0 {
        (y / rho, x / rho)
    } else {
        (0.0, 1.0)
    };
    // Bowring: tan β = z a / (ρ b).
    let ep2 = E2 / (1.0 - E2);
    let (sb, cb) = {
        let (u, v) = (z * A, rho * B);
        let n = u.hypot(v);
        if n == 0.0 { (0.0, 1.0) } else { (u / n, v / n) }
    };
    let mut s = z + ep2 * B * sb * sb * sb;
    let mut c = rho - E2 * A * cb * cb * cb;
    let n = s.hypot(c);
    s /= n;
    c /= n;
    for _ in 0..8 {
        let nn = radius_prime_vertical(s);
        let s2 = z + E2 * nn * s;
        let n = s2.hypot(rho);
        let s_new = s2 / n;
        let done = (s_new - s).abs() <= 1e-16;
        s = s_new;
        c = rho / n;
        if done {
            break;
        }
    }
    // Height from the better-conditioned of the two projections.
    let nn = radius_prime_vertical(s);
    let h = if c.abs() > 0.7 {
        rho / c - nn
    } else {
        z / s - nn * (1.0 - E2)
    };
    Geodetic {
        sin_lat: s,
        cos_lat: c,
        sin_lon,
        cos_lon,
        h,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gravity_at_equator_and_pole() {
        assert_eq!(normal_gravity(0.0, 0.0), GAMMA_E);
        // NGA.STND.0036 γ_p = 9.8321849379 (TR8350.2 rounds to …378); the closed form gives:
        assert!((normal_gravity(1.0, 0.0) - 9.832_184_937_8).abs() < 2e-10);
    }

    #[test]
    fn ecef_round_trip_everywhere() {
        for &lat_deg in &[-90.0, -89.9999, -60.0, 0.0, 41.0, 89.9999, 90.0] {
            for &h in &[-1000.0, 0.0, 10_000.0, 1.0e6] {
                let g = Geodetic::from_radians(f64::to_radians(lat_deg), 0.7, h);
                let back = ecef_to_geodetic(g.to_ecef());
                assert!(
                    (back.sin_lat - g.sin_lat).abs() < 2e-16,
                    "lat {lat_deg} h {h}"
                );
                assert!(
                    (back.cos_lat - g.cos_lat).abs() < 2e-16,
                    "lat {lat_deg} h {h}"
                );
                assert!((back.h - h).abs() < 1e-8, "lat {lat_deg} h {h}: {}", back.h);
            }
        }
    }

    #[test]
    fn c_n_e_matches_quaternion() {
        let g = Geodetic::from_radians(0.7, -2.1, 0.0);
        let m = g.c_n_e();
        let q = g.q_n_e().to_mat();
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[(i, j)] - q[(i, j)]).abs() < 1e-15);
            }
        }
    }

    /// The gradient against central differences of the gravitation built independently in
    /// ECEF: the normal gravity γ(φ, h) along the ellipsoid's normal at the geodetic point of
    /// r (as the navigator computes it), plus ω_ie × (ω_ie × r) (gravity is gravitation plus
    /// the centrifugal −ω × (ω × r)), differenced over ±10 m along each ECEF axis and turned
    /// into NED. Round-off: the ~10 m/s² values carry ≈ 2e-15 m/s² each, so the difference
    /// quotient is good to ≈ 2e-16 s⁻²; the truncation (third derivatives ~ γ/R³·δ²) is
    /// ≈ 4e-18 s⁻². 1e-14 s⁻² is 3e-9 of the 3e-6 s⁻² vertical gradient. A wrong sign of the
    /// centrifugal part misses by 2ω² ≈ 1e-8, a missing ∂γ/∂φ term by up to 8e-9.
    #[test]
    fn gravitation_gradient_is_the_fields_derivative() {
        let w = Vec3::new(0.0, 0.0, OMEGA_IE);
        let field = |r: Vec3| {
            let geo = ecef_to_geodetic(r);
            geo.up_e() * -normal_gravity(geo.sin_lat, geo.h) + w.cross(&w.cross(&r))
        };
        for (lat, lon, h) in [
            (0.0, 0.0, 0.0),
            (41.0, -3.0, 650.0),
            (-67.5, 120.0, 9000.0),
            (89.0, 10.0, 30.0),
        ] {
            let geo = Geodetic::from_radians(f64::to_radians(lat), f64::to_radians(lon), h);
            let r0 = geo.to_ecef();
            let d = 10.0;
            let columns: Vec<Vec3> = (0..3)
                .map(|i| {
                    let mut e = Vec3::zeros();
                    e[i] = d;
                    (field(r0 + e) - field(r0 - e)) / (2.0 * d)
                })
                .collect();
            let gamma_e = Mat3::from_columns(&columns);
            let c = geo.c_n_e();
            let want = c.transpose() * gamma_e * c;
            let (s, co) = f64::to_radians(lat).sin_cos();
            let got = gravitation_gradient_ned(s, co, h);
            let err = (got - want).amax();
            assert!(err < 1e-14, "{lat} {h}: {err:e}\n{got}{want}");
            assert!(got[(2, 2)] > 3.0e-6 && got[(2, 2)] < 3.2e-6, "{got}");
        }
    }
}
