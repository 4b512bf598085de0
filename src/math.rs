//! Fixed-size linear algebra in f64 on nalgebra: 3-vectors, 3×3 matrices and quaternions,
//! plus the navigation helpers nalgebra does not have in this form.
//!
//! The types are nalgebra's; the helpers keep the formulas the error budget was derived
//! with (small-angle series of the rotation vector, the `v + 2w(u×v) + 2u×(u×v)` rotation,
//! the DCM of a quaternion written with `1 − 2(…)` on the diagonal), so the numerics do
//! not depend on how nalgebra arranges the same products.

/// A 3-vector; the frame it is expressed in is carried by the variable's name (`v_n`, `f_b`).
pub type Vec3 = nalgebra::Vector3<f64>;

/// A 3×3 matrix; used for direction cosine matrices C_from^to. `Mat3::new` takes it by rows.
pub type Mat3 = nalgebra::Matrix3<f64>;

/// A quaternion `w + x i + y j + z k` (Hamilton convention; `Quat::new` takes the scalar first).
///
/// A unit quaternion `q_a_b` rotates vectors from frame a to frame b: `v_b = q_a_b.rotate(v_a)`,
/// i.e. it is the quaternion of the direction cosine matrix C_a^b. Not nalgebra's
/// `UnitQuaternion`, because the motion models interpolate and integrate quaternions whose
/// norm is not one (Hermite interpolation, Runge–Kutta stages) and normalise once at the end.
pub type Quat = nalgebra::Quaternion<f64>;

/// Rotations with a quaternion: the conversions to and from rotation vectors and matrices.
pub trait QuatExt: Sized {
    /// The unit quaternion of a rotation vector (axis × angle), exact for any angle.
    fn from_rotvec(phi: Vec3) -> Self;
    /// The rotation vector of a unit quaternion (angle in [0, π]).
    fn to_rotvec(&self) -> Vec3;
    /// Rotates a vector: q ⊗ (0, v) ⊗ q*, for a unit quaternion.
    fn rotate(&self, v: Vec3) -> Vec3;
    /// Rotates a vector by the inverse rotation (q* ⊗ v ⊗ q).
    fn rotate_inv(&self, v: Vec3) -> Vec3;
    /// Rotation matrix of a unit quaternion (C such that `C v = q.rotate(v)`).
    fn to_mat(&self) -> Mat3;
    /// The unit quaternion of the same direction: q · (w² + |v|²)^(−1/2).
    ///
    /// Not nalgebra's `normalize` (pairwise sum of squares, then four divisions): an
    /// integrator that renormalises every step accumulates that rounding differently, and the
    /// reference integration of tests/strapdown.rs ends 4–10× further from the truth with it
    /// (circle scene, 600 s: 6.5e-8 m instead of 6.6e-9 m).
    fn normalized(&self) -> Self;
}

impl QuatExt for Quat {
    fn from_rotvec(phi: Vec3) -> Quat {
        let a = phi.norm();
        if a < 1e-4 {
            // Taylor series of cos(a/2) and sin(a/2)/a: terms beyond a^4 are below 1e-17.
            let a2 = a * a;
            let c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
            let s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;
            Quat::from_parts(c, phi * s)
        } else {
            let (s, c) = (0.5 * a).sin_cos();
            Quat::from_parts(c, phi * (s / a))
        }
    }

    fn to_rotvec(&self) -> Vec3 {
        let q = if self.w < 0.0 { -*self } else { *self };
        let u = q.imag();
        let s = u.norm();
        if s == 0.0 {
            return Vec3::zeros();
        }
        // atan2 keeps full relative precision for small angles, unlike acos(w).
        let angle = 2.0 * s.atan2(q.w);
        u * (angle / s)
    }

    #[inline]
    fn rotate(&self, v: Vec3) -> Vec3 {
        // v + 2w (u × v) + 2 u × (u × v), the standard expansion.
        let u = self.imag();
        let t = u.cross(&v) * 2.0;
        v + t * self.w + u.cross(&t)
    }

    #[inline]
    fn rotate_inv(&self, v: Vec3) -> Vec3 {
        self.conjugate().rotate(v)
    }

    #[inline]
    fn normalized(&self) -> Quat {
        let n2 = self.w * self.w + self.imag().norm_squared();
        *self * (1.0 / n2.sqrt())
    }

    fn to_mat(&self) -> Mat3 {
        let (w, x, y, z) = (self.w, self.i, self.j, self.k);
        Mat3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        )
    }
}

/// True when every component is finite (nalgebra's matrices have no such method).
#[inline]
pub fn all_finite(v: &Vec3) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Quaternion of C_b^n for ZYX Euler angles (roll φ, pitch θ, yaw ψ in radians):
/// C_b^n = Rz(ψ)·Ry(θ)·Rx(φ).
pub fn quat_from_euler(roll: f64, pitch: f64, yaw: f64) -> Quat {
    let (sr, cr) = (0.5 * roll).sin_cos();
    let (sp, cp) = (0.5 * pitch).sin_cos();
    let (sy, cy) = (0.5 * yaw).sin_cos();
    Quat::new(
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr,
    )
}

/// C_b^n for ZYX Euler angles given as sines and cosines of roll, pitch, yaw.
pub fn dcm_from_euler_sc(sr: f64, cr: f64, sp: f64, cp: f64, sy: f64, cy: f64) -> Mat3 {
    Mat3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// Body angular rate ω_nb^b from ZYX Euler angles and their rates:
/// [φ̇ − ψ̇ sin θ, θ̇ cos φ + ψ̇ sin φ cos θ, −θ̇ sin φ + ψ̇ cos φ cos θ].
#[inline]
pub fn omega_from_euler_rates(sr: f64, cr: f64, sp: f64, cp: f64, rates: Vec3) -> Vec3 {
    let (dr, dp, dy) = (rates.x, rates.y, rates.z);
    Vec3::new(
        dr - dy * sp,
        dp * cr + dy * sr * cp,
        -dp * sr + dy * cr * cp,
    )
}

/// ZYX Euler angles (roll, pitch, yaw) in radians of C_b^n given as a unit quaternion.
/// Yaw is in (−π, π]; at pitch ±90° roll is set to zero and yaw carries the rotation.
pub fn euler_from_quat(q: Quat) -> (f64, f64, f64) {
    let c = q.to_mat();
    let sp = (-c[(2, 0)]).clamp(-1.0, 1.0);
    let pitch = sp.asin();
    if c[(2, 1)].abs() < 1e-12 && c[(2, 2)].abs() < 1e-12 {
        let yaw = (-c[(0, 1)]).atan2(c[(1, 1)]);
        return (0.0, pitch, yaw);
    }
    let roll = c[(2, 1)].atan2(c[(2, 2)]);
    let yaw = c[(1, 0)].atan2(c[(0, 0)]);
    (roll, pitch, yaw)
}

/// How far past a state's time tag `t` a record time still counts as that instant: a record's
/// time t₀ + k/rate is computed in f64 (t₀ itself a tag read from the input), so the record that
/// falls on a state's own time can come out an ulp or two after the tag read for it (seen:
/// 1.2e-10 s at 5.7e5 s, GPS seconds of the week). Both roundings are within half an ulp of the
/// larger of |t|, |t₀|, the sum's and the quotient's within one more: four ulps cover them all.
/// Being that far past the newest state, the record extrapolates by less than
/// 4·[`crate::engine::TIME_RESOLUTION`] of its interval (a grid finer than that is refused).
pub fn tag_slack(t: f64, t0: f64) -> f64 {
    let m = t.abs().max(t0.abs());
    4.0 * (f64::from_bits(m.to_bits() + 1) - m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn euler_quat_and_dcm_agree() {
        let (r, p, y) = (0.3_f64, -1.1_f64, 2.9_f64);
        let q = quat_from_euler(r, p, y);
        let m = dcm_from_euler_sc(r.sin(), r.cos(), p.sin(), p.cos(), y.sin(), y.cos());
        let qm = q.to_mat();
        for i in 0..3 {
            for j in 0..3 {
                assert!((m[(i, j)] - qm[(i, j)]).abs() < 1e-15);
            }
        }
        let (r2, p2, y2) = euler_from_quat(q);
        assert!((r2 - r).abs() < 1e-14 && (p2 - p).abs() < 1e-14 && (y2 - y).abs() < 1e-14);
    }

    #[test]
    fn rotvec_round_trip_small_and_large() {
        for phi in [Vec3::new(1e-9, -2e-9, 3e-10), Vec3::new(0.4, -2.0, 1.1)] {
            let back = Quat::from_rotvec(phi).to_rotvec();
            assert!((back - phi).amax() < 1e-15 * phi.norm().max(1.0));
        }
    }
}
