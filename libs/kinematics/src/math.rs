//! Small 3-D rigid-body arithmetic: rotations as 3 × 3 matrices, poses as a rotation and a
//! translation. Enough for the legs, with no linear-algebra crate.

/// A 3-vector.
pub type V3 = [f64; 3];
/// A rotation matrix, row-major.
pub type M3 = [[f64; 3]; 3];

/// The identity rotation.
pub const I3: M3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Rotation about x by `t` rad.
pub fn rx(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
}

/// Rotation about y by `t` rad.
pub fn ry(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]
}

/// Rotation about z by `t` rad.
pub fn rz(t: f64) -> M3 {
    let (s, c) = t.sin_cos();
    [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
}

/// a · b.
pub fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// aᵀ.
pub fn tr(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

/// a · v.
pub fn mv(a: &M3, v: &V3) -> V3 {
    std::array::from_fn(|i| a[i][0] * v[0] + a[i][1] * v[1] + a[i][2] * v[2])
}

/// a + b.
pub fn add(a: &V3, b: &V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// a − b.
pub fn sub(a: &V3, b: &V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// |v|.
pub fn norm(v: &V3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// A rigid pose: rotation and translation (a frame's axes and origin in its parent).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Rotation.
    pub r: M3,
    /// Translation, m.
    pub p: V3,
}

impl Default for Pose {
    fn default() -> Pose {
        Pose::IDENTITY
    }
}

impl Pose {
    /// No rotation, no translation.
    pub const IDENTITY: Pose = Pose { r: I3, p: [0.0; 3] };

    /// A translation.
    pub fn at(p: V3) -> Pose {
        Pose { r: I3, p }
    }

    /// A rotation.
    pub fn rot(r: M3) -> Pose {
        Pose { r, p: [0.0; 3] }
    }

    /// Upright at `p` with heading `yaw`.
    pub fn yawed(p: V3, yaw: f64) -> Pose {
        Pose { r: rz(yaw), p }
    }

    /// self · other.
    pub fn then(&self, o: &Pose) -> Pose {
        Pose {
            r: mul(&self.r, &o.r),
            p: add(&self.p, &mv(&self.r, &o.p)),
        }
    }

    /// The inverse.
    pub fn inv(&self) -> Pose {
        let rt = tr(&self.r);
        let p = mv(&rt, &self.p);
        Pose {
            r: rt,
            p: [-p[0], -p[1], -p[2]],
        }
    }

    /// A point of this frame in the parent.
    pub fn apply(&self, q: &V3) -> V3 {
        add(&self.p, &mv(&self.r, q))
    }

    /// The largest difference to `o`: translation (m) and rotation (Frobenius norm of the
    /// difference of the matrices).
    pub fn distance(&self, o: &Pose) -> (f64, f64) {
        let dp = norm(&sub(&self.p, &o.p));
        let dr: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| (self.r[i][j] - o.r[i][j]).powi(2))
            .sum::<f64>()
            .sqrt();
        (dp, dr)
    }
}
