//! Small fixed-size linear algebra in f64: 3-vectors, 3×3 matrices and quaternions.
//!
//! Hand-rolled rather than a general crate because the hot path needs only these few
//! operations, they inline completely, and the build stays light (see docs/design.md).

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

/// A 3-vector; the frame it is expressed in is carried by the variable's name (`v_n`, `f_b`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3(pub [f64; 3]);

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3([0.0; 3]);
    /// Builds a vector from its three components.
    #[inline]
    pub const fn new(x: f64, y: f64, z: f64) -> Vec3 {
        Vec3([x, y, z])
    }
    /// Component x (or north).
    #[inline]
    pub fn x(self) -> f64 {
        self.0[0]
    }
    /// Component y (or east).
    #[inline]
    pub fn y(self) -> f64 {
        self.0[1]
    }
    /// Component z (or down).
    #[inline]
    pub fn z(self) -> f64 {
        self.0[2]
    }
    /// Dot product.
    #[inline]
    pub fn dot(self, o: Vec3) -> f64 {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }
    /// Cross product self × o.
    #[inline]
    pub fn cross(self, o: Vec3) -> Vec3 {
        let [a, b, c] = self.0;
        let [d, e, f] = o.0;
        Vec3([b * f - c * e, c * d - a * f, a * e - b * d])
    }
    /// Euclidean norm.
    #[inline]
    pub fn norm(self) -> f64 {
        self.dot(self).sqrt()
    }
    /// Largest absolute component.
    #[inline]
    pub fn max_abs(self) -> f64 {
        self.0[0].abs().max(self.0[1].abs()).max(self.0[2].abs())
    }
    /// True when every component is finite.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}
impl AddAssign for Vec3 {
    #[inline]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}
impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}
impl Neg for Vec3 {
    type Output = Vec3;
    #[inline]
    fn neg(self) -> Vec3 {
        Vec3([-self.0[0], -self.0[1], -self.0[2]])
    }
}
impl Mul<f64> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, s: f64) -> Vec3 {
        Vec3([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
}
impl Mul<Vec3> for f64 {
    type Output = Vec3;
    #[inline]
    fn mul(self, v: Vec3) -> Vec3 {
        v * self
    }
}

/// A 3×3 matrix stored by rows; used for direction cosine matrices C_from^to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat3(pub [[f64; 3]; 3]);

impl Mat3 {
    /// The identity.
    pub const IDENTITY: Mat3 = Mat3([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    /// Matrix × vector.
    #[inline]
    pub fn mul_vec(&self, v: Vec3) -> Vec3 {
        let m = &self.0;
        Vec3([
            m[0][0] * v.0[0] + m[0][1] * v.0[1] + m[0][2] * v.0[2],
            m[1][0] * v.0[0] + m[1][1] * v.0[1] + m[1][2] * v.0[2],
            m[2][0] * v.0[0] + m[2][1] * v.0[1] + m[2][2] * v.0[2],
        ])
    }
    /// Transpose × vector (the inverse rotation for an orthonormal matrix).
    #[inline]
    pub fn tr_mul_vec(&self, v: Vec3) -> Vec3 {
        let m = &self.0;
        Vec3([
            m[0][0] * v.0[0] + m[1][0] * v.0[1] + m[2][0] * v.0[2],
            m[0][1] * v.0[0] + m[1][1] * v.0[1] + m[2][1] * v.0[2],
            m[0][2] * v.0[0] + m[1][2] * v.0[1] + m[2][2] * v.0[2],
        ])
    }
    /// Matrix product self · o.
    pub fn mul_mat(&self, o: &Mat3) -> Mat3 {
        let mut r = [[0.0; 3]; 3];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell = (0..3).map(|k| self.0[i][k] * o.0[k][j]).sum();
            }
        }
        Mat3(r)
    }
    /// Transpose.
    pub fn transpose(&self) -> Mat3 {
        let m = &self.0;
        Mat3([
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ])
    }
}

/// A quaternion `w + x i + y j + z k` (Hamilton convention, scalar first).
///
/// A unit quaternion `q_a_b` rotates vectors from frame a to frame b: `v_b = q_a_b.rotate(v_a)`,
/// i.e. it is the quaternion of the direction cosine matrix C_a^b.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quat {
    /// Scalar part.
    pub w: f64,
    /// Vector part.
    pub v: Vec3,
}

impl Quat {
    /// The identity rotation.
    pub const IDENTITY: Quat = Quat {
        w: 1.0,
        v: Vec3::ZERO,
    };
    /// Builds a quaternion from its four components.
    #[inline]
    pub const fn new(w: f64, x: f64, y: f64, z: f64) -> Quat {
        Quat {
            w,
            v: Vec3([x, y, z]),
        }
    }
    /// Hamilton product self ⊗ o (also the `*` operator).
    #[inline]
    #[allow(clippy::should_implement_trait)] // inherent, so callers need no trait import
    pub fn mul(self, o: Quat) -> Quat {
        Quat {
            w: self.w * o.w - self.v.dot(o.v),
            v: o.v * self.w + self.v * o.w + self.v.cross(o.v),
        }
    }
    /// Conjugate (the inverse of a unit quaternion).
    #[inline]
    pub fn conj(self) -> Quat {
        Quat {
            w: self.w,
            v: -self.v,
        }
    }
    /// 4-D dot product.
    #[inline]
    pub fn dot4(self, o: Quat) -> f64 {
        self.w * o.w + self.v.dot(o.v)
    }
    /// Squared 4-D norm.
    #[inline]
    pub fn norm2(self) -> f64 {
        self.dot4(self)
    }
    /// Scales all four components.
    #[inline]
    pub fn scale(self, s: f64) -> Quat {
        Quat {
            w: self.w * s,
            v: self.v * s,
        }
    }
    /// Component-wise sum (also the `+` operator).
    #[inline]
    #[allow(clippy::should_implement_trait)] // inherent, so callers need no trait import
    pub fn add(self, o: Quat) -> Quat {
        Quat {
            w: self.w + o.w,
            v: self.v + o.v,
        }
    }
    /// Normalized copy.
    #[inline]
    pub fn normalized(self) -> Quat {
        self.scale(1.0 / self.norm2().sqrt())
    }
    /// Rotates a vector: q ⊗ (0, v) ⊗ q*, for a unit quaternion.
    #[inline]
    pub fn rotate(self, v: Vec3) -> Vec3 {
        // v + 2w (u × v) + 2 u × (u × v), the standard expansion.
        let t = self.v.cross(v) * 2.0;
        v + t * self.w + self.v.cross(t)
    }
    /// Rotates a vector by the inverse rotation (q* ⊗ v ⊗ q).
    #[inline]
    pub fn rotate_inv(self, v: Vec3) -> Vec3 {
        self.conj().rotate(v)
    }
    /// Rotation matrix of a unit quaternion (C such that `C v = q.rotate(v)`).
    pub fn to_mat(self) -> Mat3 {
        let (w, [x, y, z]) = (self.w, self.v.0);
        Mat3([
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ])
    }
    /// The unit quaternion of a rotation vector (axis × angle), exact for any angle.
    pub fn from_rotvec(phi: Vec3) -> Quat {
        let a = phi.norm();
        if a < 1e-4 {
            // Taylor series of cos(a/2) and sin(a/2)/a: terms beyond a^4 are below 1e-17.
            let a2 = a * a;
            let c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0;
            let s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0;
            Quat { w: c, v: phi * s }
        } else {
            let (s, c) = (0.5 * a).sin_cos();
            Quat {
                w: c,
                v: phi * (s / a),
            }
        }
    }
    /// The rotation vector of a unit quaternion (angle in [0, π]).
    pub fn to_rotvec(self) -> Vec3 {
        let q = if self.w < 0.0 { self.scale(-1.0) } else { self };
        let s = q.v.norm();
        if s == 0.0 {
            return Vec3::ZERO;
        }
        // atan2 keeps full relative precision for small angles, unlike acos(w).
        let angle = 2.0 * s.atan2(q.w);
        q.v * (angle / s)
    }
}

impl Mul for Quat {
    type Output = Quat;
    #[inline]
    fn mul(self, o: Quat) -> Quat {
        Quat::mul(self, o)
    }
}

impl Add for Quat {
    type Output = Quat;
    #[inline]
    fn add(self, o: Quat) -> Quat {
        Quat::add(self, o)
    }
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
    Mat3([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
}

/// Body angular rate ω_nb^b from ZYX Euler angles and their rates:
/// [φ̇ − ψ̇ sin θ, θ̇ cos φ + ψ̇ sin φ cos θ, −θ̇ sin φ + ψ̇ cos φ cos θ].
#[inline]
pub fn omega_from_euler_rates(sr: f64, cr: f64, sp: f64, cp: f64, rates: Vec3) -> Vec3 {
    let [dr, dp, dy] = rates.0;
    Vec3([
        dr - dy * sp,
        dp * cr + dy * sr * cp,
        -dp * sr + dy * cr * cp,
    ])
}

/// ZYX Euler angles (roll, pitch, yaw) in radians of C_b^n given as a unit quaternion.
/// Yaw is in (−π, π]; at pitch ±90° roll is set to zero and yaw carries the rotation.
pub fn euler_from_quat(q: Quat) -> (f64, f64, f64) {
    let c = q.to_mat().0;
    let sp = (-c[2][0]).clamp(-1.0, 1.0);
    let pitch = sp.asin();
    if c[2][1].abs() < 1e-12 && c[2][2].abs() < 1e-12 {
        let yaw = (-c[0][1]).atan2(c[1][1]);
        return (0.0, pitch, yaw);
    }
    let roll = c[2][1].atan2(c[2][2]);
    let yaw = c[1][0].atan2(c[0][0]);
    (roll, pitch, yaw)
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
                assert!((m.0[i][j] - qm.0[i][j]).abs() < 1e-15);
            }
        }
        let (r2, p2, y2) = euler_from_quat(q);
        assert!((r2 - r).abs() < 1e-14 && (p2 - p).abs() < 1e-14 && (y2 - y).abs() < 1e-14);
    }

    #[test]
    fn rotvec_round_trip_small_and_large() {
        for phi in [Vec3::new(1e-9, -2e-9, 3e-10), Vec3::new(0.4, -2.0, 1.1)] {
            let back = Quat::from_rotvec(phi).to_rotvec();
            assert!((back - phi).max_abs() < 1e-15 * phi.norm().max(1.0));
        }
    }
}
