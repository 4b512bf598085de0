//! Where a unit sits on the body: the error-free signal of a sensor at a point away from the
//! trajectory's reference point, and in axes turned from the body's. Pure math, no I/O.
//!
//! A rigid body turning at ω with angular acceleration ω̇ carries a point at r (body frame,
//! from the reference point) with specific force f_r = f + ω̇ × r + ω × (ω × r)
//! (Titterton & Weston, *Strapdown Inertial Navigation Technology*, 2nd ed., §10.4, the
//! lever-arm correction). Both added terms are linear in quantities whose interval means the
//! generator gives exactly: mean(ω̇) = Δω/Δt, and ω × (ω × r) = (ω ωᵀ − |ω|² I) r is linear in
//! ω ωᵀ, whose interval mean it integrates by the same quadrature as f. So the interval mean is
//! f̄ + (Δω/Δt) × r + (W − tr W · I) r with W the mean of ω ωᵀ, with no differentiation of ω.
//! The angular rate is the same at every point of a rigid body. The gravitation differs across
//! the lever arm by Γ r (Γ its gradient, [`crate::earth::gravitation_gradient_ned`]), so the
//! specific force there has −Γ r more: about 3·10⁻⁶ s⁻² vertically, which an error-free unit
//! at 1.5 m would otherwise turn into ½·4.6·10⁻⁶·t² m of drift in a navigator.

use crate::generator::RotationTerms;
use crate::math::{Mat3, QuatExt, Vec3};

/// Interval mean of the specific force at `r` (body frame, m) given the reference point's
/// interval mean `f_mean` and the interval's rotation terms; `inv_dt` = 1/Δt.
#[inline]
pub fn force_at(f_mean: Vec3, rot: &RotationTerms, inv_dt: f64, r: Vec3) -> Vec3 {
    let w = &rot.omega_outer;
    f_mean + (rot.d_omega * inv_dt).cross(&r) + w * r - r * w.trace() - rot.gravitation * r
}

/// The rotation terms seen in axes turned by `c` (C_b^c): Δω^c = C Δω^b, W^c = C W Cᵀ, for
/// error stages of the unit (a template's own accelerometer offsets) that work in its axes.
pub fn rotate_terms(rot: &RotationTerms, c: &Mat3) -> RotationTerms {
    RotationTerms {
        d_omega: c * rot.d_omega,
        omega_outer: c * rot.omega_outer * c.transpose(),
        gravitation: c * rot.gravitation * c.transpose(),
    }
}

/// A unit's place on the body: its axes (C_b^c, from the mounting angles) and the lever arm
/// from the reference point to its reference point (body frame, m).
#[derive(Clone, Debug, PartialEq)]
pub struct Placement {
    /// C_b^c, or `None` when the unit's axes are the body's.
    pub c_b_c: Option<Mat3>,
    /// Lever arm (body frame, m).
    pub lever_b: Vec3,
}

impl Placement {
    /// The placement of a unit mounted at [roll, pitch, yaw] (degrees, C_c^b as the
    /// existing `imu.mounting_deg`) with lever arm `lever_b` (body frame, m).
    pub fn new(mounting_deg: [f64; 3], lever_b: [f64; 3]) -> Placement {
        let [r, p, y] = mounting_deg.map(f64::to_radians);
        let c_c_b = crate::math::quat_from_euler(r, p, y).to_mat();
        Placement {
            c_b_c: (c_c_b != Mat3::identity()).then(|| c_c_b.transpose()),
            lever_b: Vec3::from(lever_b),
        }
    }

    /// Whether the unit sits at the reference point in the body's axes.
    pub fn is_identity(&self) -> bool {
        self.c_b_c.is_none() && self.lever_b == Vec3::zeros()
    }

    /// A body-frame vector in the unit's axes.
    #[inline]
    pub fn to_case(&self, v: Vec3) -> Vec3 {
        self.c_b_c.as_ref().map_or(v, |c| c * v)
    }

    /// A vector in the unit's axes in the body frame.
    #[inline]
    pub fn to_body(&self, v: Vec3) -> Vec3 {
        self.c_b_c.as_ref().map_or(v, |c| c.tr_mul(&v))
    }

    /// The body-frame position of a point at `p_case` (unit axes, m, from the unit's
    /// reference point).
    #[inline]
    pub fn point_b(&self, p_case: Vec3) -> Vec3 {
        self.lever_b + self.to_body(p_case)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Constant rate ω about z and no angular acceleration: a point at r = (x, y, h) feels
    /// the centripetal −ω²(x, y, 0) exactly (round-off only); with constant angular
    /// acceleration α about z and ω = 0 over the interval's mean, the tangential α ẑ × r.
    #[test]
    fn lever_arm_terms_match_the_closed_forms() {
        let (w, r) = (2.5, Vec3::new(0.3, -1.2, 0.7));
        let rot = RotationTerms {
            d_omega: Vec3::zeros(),
            omega_outer: Mat3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, w * w),
            gravitation: Mat3::zeros(),
        };
        let f = force_at(Vec3::new(0.0, 0.0, -9.8), &rot, 100.0, r);
        let expect = Vec3::new(-w * w * 0.3, w * w * 1.2, -9.8);
        assert!((f - expect).amax() <= 4.0 * f64::EPSILON * 9.8, "{f:?}");
        // α = 3 rad/s² over Δt = 0.01 s: Δω = 0.03 rad/s; ω ωᵀ taken as zero here.
        let rot = RotationTerms {
            d_omega: Vec3::new(0.0, 0.0, 0.03),
            omega_outer: Mat3::zeros(),
            gravitation: Mat3::zeros(),
        };
        let f = force_at(Vec3::zeros(), &rot, 100.0, r);
        let expect = Vec3::new(3.0 * 1.2, 3.0 * 0.3, 0.0);
        assert!((f - expect).amax() <= 8.0 * f64::EPSILON * 3.6, "{f:?}");
        // The gravitation's gradient Γ: the point reads −Γ r more (level, at rest: a unit
        // 0.7 m below the reference point reads (2g/R)·0.7 more downward force… less upward).
        let g = crate::earth::gravitation_gradient_ned(0.0, 1.0, 0.0);
        let rot = RotationTerms {
            gravitation: g,
            ..RotationTerms::default()
        };
        let f = force_at(Vec3::zeros(), &rot, 100.0, r);
        assert!((f + g * r).amax() <= 1e-20, "{f:?}");
        assert!(f[2] < -2.0e-6 && f[2] > -2.3e-6, "{f:?}");
    }

    /// A unit yawed 90°: body x is its −y… the body's x axis reads along the unit's −y,
    /// and W turned into its axes is C W Cᵀ (checked element by element).
    #[test]
    fn placement_turns_vectors_and_terms() {
        let p = Placement::new([0.0, 0.0, 90.0], [1.0, 0.0, 0.0]);
        let v = p.to_case(Vec3::new(1.0, 0.0, 0.0));
        assert!((v - Vec3::new(0.0, -1.0, 0.0)).amax() < 1e-15, "{v:?}");
        let back = p.to_body(v);
        assert!((back - Vec3::new(1.0, 0.0, 0.0)).amax() < 1e-15);
        // A point 0.5 m along the unit's x is 0.5 m along body y, plus the lever arm.
        let q = p.point_b(Vec3::new(0.5, 0.0, 0.0));
        assert!((q - Vec3::new(1.0, 0.5, 0.0)).amax() < 1e-15, "{q:?}");
        let rot = RotationTerms {
            d_omega: Vec3::new(1.0, 2.0, 3.0),
            omega_outer: Mat3::new(1.0, 2.0, 0.0, 2.0, 4.0, 0.0, 0.0, 0.0, 9.0),
            gravitation: Mat3::new(1.0, 2.0, 0.0, 2.0, 4.0, 0.0, 0.0, 0.0, 9.0),
        };
        let t = rotate_terms(&rot, p.c_b_c.as_ref().unwrap());
        assert!((t.d_omega - Vec3::new(2.0, -1.0, 3.0)).amax() < 1e-15);
        let expect = Mat3::new(4.0, -2.0, 0.0, -2.0, 1.0, 0.0, 0.0, 0.0, 9.0);
        assert!((t.omega_outer - expect).amax() < 1e-14, "{}", t.omega_outer);
        assert!((t.gravitation - expect).amax() < 1e-14, "{}", t.gravitation);
    }
}
