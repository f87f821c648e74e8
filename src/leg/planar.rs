//! Minimal planar (sagittal x-z plane) rigid transforms, independent of Rapier.
//!
//! A [`Pose2`] maps child coordinates to parent coordinates:
//! `p_parent = R_y(angle) * p_child + (x, z)`, where `R_y(a)` is the right-handed rotation about
//! +y: `x' = x cos a + z sin a`, `z' = -x sin a + z cos a`. Lengths in m, angles in rad.

/// A point or vector in the x-z plane, m.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct P2 {
    /// x (forward), m.
    pub x: f64,
    /// z (up), m.
    pub z: f64,
}

impl P2 {
    /// New point.
    pub const fn new(x: f64, z: f64) -> Self {
        Self { x, z }
    }
    /// Euclidean norm.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.z)
    }
    /// Dot product.
    pub fn dot(self, o: P2) -> f64 {
        self.x * o.x + self.z * o.z
    }
    /// Rotate by `a` about +y.
    pub fn rot(self, a: f64) -> P2 {
        let (s, c) = a.sin_cos();
        P2::new(self.x * c + self.z * s, -self.x * s + self.z * c)
    }
    /// Polar angle such that `P2::new(0,1).rot(polar) == self/|self|` (atan2(x, z)).
    pub fn polar(self) -> f64 {
        self.x.atan2(self.z)
    }
    /// Sum.
    pub fn plus(self, o: P2) -> P2 {
        P2::new(self.x + o.x, self.z + o.z)
    }
    /// Difference.
    pub fn minus(self, o: P2) -> P2 {
        P2::new(self.x - o.x, self.z - o.z)
    }
    /// Scale.
    pub fn scale(self, k: f64) -> P2 {
        P2::new(self.x * k, self.z * k)
    }
}

/// Planar rigid transform (translation in x-z, rotation about +y).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Pose2 {
    /// Translation, m.
    pub t: P2,
    /// Rotation about +y, rad.
    pub a: f64,
}

impl Pose2 {
    /// Identity.
    pub const IDENTITY: Pose2 = Pose2 { t: P2::new(0.0, 0.0), a: 0.0 };
    /// New pose.
    pub fn new(x: f64, z: f64, a: f64) -> Self {
        Self { t: P2::new(x, z), a }
    }
    /// Pure rotation about +y.
    pub fn rot(a: f64) -> Self {
        Self { t: P2::default(), a }
    }
    /// Pure translation.
    pub fn trans(t: P2) -> Self {
        Self { t, a: 0.0 }
    }
    /// Composition `self * o` (apply `o` first).
    pub fn mul(&self, o: &Pose2) -> Pose2 {
        Pose2 { t: self.t.plus(o.t.rot(self.a)), a: self.a + o.a }
    }
    /// Transform a point.
    pub fn apply(&self, p: P2) -> P2 {
        self.t.plus(p.rot(self.a))
    }
}
