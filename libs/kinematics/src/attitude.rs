//! The body's attitude from an IMU: a complementary filter of the gyro's rates and the
//! accelerometer's gravity direction (the Arduino boards' MPU-6050; the stabiliser to come).

use nalgebra::UnitQuaternion;

/// A complementary filter: roll and pitch from the gyro, pulled towards the accelerometer's
/// gravity direction with time constant `tau`; yaw from the gyro alone.
#[derive(Debug, Clone)]
pub struct Attitude {
    tau: f64,
    /// Roll, pitch, yaw, rad.
    pub rpy: [f64; 3],
    started: bool,
}

impl Attitude {
    /// A filter with time constant `tau` seconds.
    pub fn new(tau: f64) -> Attitude {
        Attitude {
            tau,
            rpy: [0.0; 3],
            started: false,
        }
    }

    /// Takes one sample (accelerometer in g, gyro in rad/s) `dt` seconds after the last.
    pub fn update(&mut self, accel: [f64; 3], gyro: [f64; 3], dt: f64) {
        let roll_acc = accel[1].atan2(accel[2]);
        let pitch_acc = (-accel[0]).atan2((accel[1] * accel[1] + accel[2] * accel[2]).sqrt());
        if !self.started {
            // Start from the accelerometer, not from zero.
            self.rpy = [roll_acc, pitch_acc, 0.0];
            self.started = true;
            return;
        }
        let a = self.tau / (self.tau + dt.max(0.0));
        self.rpy[0] = a * (self.rpy[0] + gyro[0] * dt) + (1.0 - a) * roll_acc;
        self.rpy[1] = a * (self.rpy[1] + gyro[1] * dt) + (1.0 - a) * pitch_acc;
        self.rpy[2] += gyro[2] * dt;
    }

    /// The attitude as a quaternion (w, x, y, z): yaw about z, then pitch about y, then roll
    /// about x (R = Rz · Ry · Rx).
    pub fn quaternion(&self) -> [f64; 4] {
        let [r, p, y] = self.rpy;
        let q = UnitQuaternion::from_euler_angles(r, p, y);
        [q.w, q.i, q.j, q.k]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quaternion_is_yaw_then_pitch_then_roll() {
        let mut a = Attitude::new(0.5);
        a.rpy = [0.3, -0.2, 1.1];
        let [w, x, y, z] = a.quaternion();
        // Composed by hand from the three half-angle quaternions qz · qy · qx.
        let h = |t: f64| ((t / 2.0).cos(), (t / 2.0).sin());
        let ((cr, sr), (cp, sp), (cy, sy)) = (h(0.3), h(-0.2), h(1.1));
        let want = [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ];
        for (g, w2) in [w, x, y, z].iter().zip(want) {
            assert!(
                (g - w2).abs() < 1e-12,
                "{:?} against {want:?}",
                [w, x, y, z]
            );
        }
    }
}
