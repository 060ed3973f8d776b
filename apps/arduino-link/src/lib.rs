//! The logic of `stride-arduino-link`: configuration, the limits every command is checked
//! against, the complementary filter that turns the MPU-6050's raw samples into the hip's
//! attitude, and the LCM messages. The link itself is `stride-link`'s.

use stride_lcmtypes::stride::{ArduinoJointStateT, HeaderT, ImuT, JointCommandT, JointStateT};
use stride_link::{JointCommand, JointState};
use stride_serial::LineSpec;

mod app;

pub use app::{ArduinoApp, Cli};

/// One joint of the board.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointConfig {
    /// Joint name (as in commands and states).
    pub name: String,
    /// Index on the board (0..joints).
    pub index: u8,
    /// Largest duty this joint may be commanded, in (0, 1].
    pub max_duty: f64,
    /// Position limits for position commands, rad.
    pub min_position: f64,
    /// Upper position limit, rad.
    pub max_position: f64,
}

impl JointConfig {
    /// The joint's limits as every bridge checks them (position only: the board takes no
    /// speed).
    pub fn limits(&self) -> stride_limits::Limits {
        stride_limits::Limits {
            min_position: self.min_position,
            max_position: self.max_position,
            max_velocity: f64::INFINITY,
        }
    }
}

/// The app's TOML configuration.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LinkConfig {
    /// Serial device of the board (prefer a `/dev/serial/by-id/...` name: it is the same after
    /// the board is plugged back in), or `sim` for a fake board in this process.
    pub port: LineSpec,
    /// Baud rate.
    pub baud: u32,
    /// Name of the board (in states and logs).
    pub board: String,
    /// Loop rate: commands out, heartbeats when there are none, Hz.
    pub rate_hz: f64,
    /// How long the board may take to answer the handshake after the port opens (opening it
    /// resets the Due: its boot loader runs first), ms.
    pub handshake_timeout_ms: u64,
    /// Wait between attempts to reopen a port that vanished, ms.
    pub reconnect_ms: u64,
    /// A joint whose current goes above this is braked by the host and reported, A.
    pub current_limit_a: f64,
    /// Time constant of the attitude filter (the accelerometer's weight against the gyro), s.
    pub imu_time_constant_s: f64,
    /// Channel of incoming `stride.joint_command_t`.
    pub command_channel: String,
    /// Channel of outgoing `stride.arduino_joint_state_t`.
    pub state_channel: String,
    /// Channel of outgoing `stride.joint_state_t`.
    pub joint_state_channel: String,
    /// Channel of outgoing `stride.imu_t` (raw sample in SI units, attitude from the filter).
    pub imu_channel: String,
    /// The joints.
    pub joint: Vec<JointConfig>,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            port: LineSpec::Sim,
            baud: 115_200,
            board: "board".into(),
            rate_hz: 100.0,
            handshake_timeout_ms: 3000,
            reconnect_ms: 500,
            current_limit_a: 6.0,
            imu_time_constant_s: 0.5,
            command_channel: "JOINT_COMMAND".into(),
            state_channel: "ARDUINO_STATE".into(),
            joint_state_channel: "JOINT_STATE".into(),
            imu_channel: "IMU".into(),
            joint: Vec::new(),
        }
    }
}

impl LinkConfig {
    /// Checks what serde cannot.
    pub fn check(&self) -> Result<(), String> {
        if self.joint.is_empty() {
            return Err("the configuration lists no [[joint]]".into());
        }
        if !(1.0..=1000.0).contains(&self.rate_hz) {
            return Err(format!("rate_hz {} outside 1..=1000", self.rate_hz));
        }
        let mut seen = std::collections::BTreeSet::new();
        for j in &self.joint {
            if !seen.insert(j.index) || j.index > 7 {
                return Err(format!(
                    "joint {}: index {} used twice or above 7",
                    j.name, j.index
                ));
            }
            if !(j.max_duty > 0.0 && j.max_duty <= 1.0) {
                return Err(format!("joint {}: max_duty must be in (0, 1]", j.name));
            }
            j.limits().check(&j.name)?;
            // The link carries positions as 1e-4 rad in an i16.
            if j.min_position < -3.2 || j.max_position > 3.2 {
                return Err(format!(
                    "joint {}: position limits must be within ±3.2 rad",
                    j.name
                ));
            }
        }
        Ok(())
    }

    /// Checks a command against every limit and turns it into the board's set-points; nothing
    /// of a command that breaks one is sent. Each joint named once; duty within its
    /// `max_duty`, position within its limits (the check every bridge makes, `stride-limits`).
    pub fn to_board(&self, c: &JointCommandT) -> Result<Vec<JointCommand>, Reject> {
        stride_limits::lengths(
            c.names.len(),
            &[("modes", c.modes.len()), ("set-points", c.setpoints.len())],
        )?;
        let cols =
            stride_limits::columns(&c.names, |n| self.joint.iter().position(|j| j.name == n))?;
        let mut out = Vec::with_capacity(cols.len());
        for (k, &i) in cols.iter().enumerate() {
            let j = &self.joint[i];
            let v = c.setpoints[k];
            let unfit = |what: String| Reject::Limit {
                joint: j.name.clone(),
                what,
            };
            let command = match c.modes[k] {
                JointCommandT::MODE_DUTY => {
                    if v.is_nan() || v.abs() > j.max_duty {
                        return Err(unfit(format!("duty {v:.3} beyond ±{}", j.max_duty)));
                    }
                    JointCommand::duty(j.index, v)
                        .ok_or_else(|| unfit(format!("duty {v:.3} beyond the wire's ±3.2767")))?
                }
                JointCommandT::MODE_POSITION => {
                    j.limits().position(&j.name, v)?;
                    JointCommand::position(j.index, v).ok_or_else(|| {
                        unfit(format!("position {v:.4} rad beyond the wire's ±3.2767 rad"))
                    })?
                }
                JointCommandT::MODE_BRAKE => JointCommand::brake(j.index),
                JointCommandT::MODE_DISABLE => JointCommand::coast(j.index),
                _ => {
                    return Err(Reject::Mode {
                        joint: j.name.clone(),
                        what: "the board takes duty, position, brake and disable".into(),
                    })
                }
            };
            out.push(command);
        }
        Ok(out)
    }

    /// A command that brakes every joint.
    pub fn brake_all(&self) -> Vec<JointCommand> {
        self.joint
            .iter()
            .map(|j| JointCommand::brake(j.index))
            .collect()
    }
}

/// Why a command was refused: the check every bridge makes.
pub use stride_limits::Reject;

pub use stride_link::imu;

pub use stride_kinematics::attitude::Attitude;

/// The board's raw sample as `stride.imu_t`, with the filter's attitude.
pub fn imu_msg(
    header: HeaderT,
    accel: [i16; 3],
    temperature: i16,
    gyro: [i16; 3],
    att: &Attitude,
) -> ImuT {
    ImuT {
        header,
        orientation: att.quaternion(),
        angular_velocity: imu::gyro_rad_s(gyro),
        linear_acceleration: imu::accel_g(accel).map(|a| a * imu::G),
        temperature: imu::temperature_c(temperature) as f32,
    }
}

/// The board's STATE as `stride.arduino_joint_state_t` and `stride.joint_state_t`.
pub fn state_msgs(
    cfg: &LinkConfig,
    header: HeaderT,
    firmware: &str,
    joints: &[JointState],
    imu: ([i16; 3], [i16; 3]),
    link_errors: i32,
) -> (ArduinoJointStateT, JointStateT) {
    let picked: Vec<(&JointConfig, JointState)> = cfg
        .joint
        .iter()
        .filter_map(|j| joints.get(j.index as usize).map(|s| (j, *s)))
        .collect();
    let n = picked.len();
    let names: Vec<String> = picked.iter().map(|(j, _)| j.name.clone()).collect();
    let positions: Vec<f64> = picked.iter().map(|(_, s)| s.position_rad()).collect();
    let velocities: Vec<f64> = picked.iter().map(|(_, s)| s.velocity_rad_s()).collect();
    let currents: Vec<f32> = picked.iter().map(|(_, s)| s.current_a() as f32).collect();
    let temperatures: Vec<f32> = picked.iter().map(|(_, s)| s.temperature as f32).collect();
    let faults: Vec<i8> = picked.iter().map(|(_, s)| s.faults() as i8).collect();
    let arduino = ArduinoJointStateT {
        header: header.clone(),
        port: cfg.port.to_string(),
        firmware: firmware.to_owned(),
        num_joints: n as i32,
        joint_names: names.clone(),
        positions: positions.clone(),
        velocities: velocities.clone(),
        currents: currents.clone(),
        temperatures: temperatures.clone(),
        duty: picked
            .iter()
            .map(|(_, s)| s.duty as f32 / 10_000.0)
            .collect(),
        brake: picked.iter().map(|(_, s)| s.flags & 1 == 1).collect(),
        faults: faults.clone(),
        imu_accel: imu.0,
        imu_gyro: imu.1,
        link_errors,
    };
    let js = JointStateT {
        header,
        num_joints: n as i32,
        names,
        positions,
        velocities,
        currents: currents.iter().map(|&c| c as f64).collect(),
        temperatures,
        faults: faults.iter().map(|&f| f as i32).collect(),
    };
    (arduino, js)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shipped(name: &str) -> LinkConfig {
        let path = format!("{}/../../config/robots/{name}", env!("CARGO_MANIFEST_DIR"));
        toml::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    fn cmd(name: &str, mode: i8, v: f64) -> JointCommandT {
        JointCommandT {
            num_joints: 1,
            names: vec![name.into()],
            modes: vec![mode],
            setpoints: vec![v],
            velocities: vec![0.0],
            ..Default::default()
        }
    }

    #[test]
    fn shipped_configs_and_limits() {
        for f in [
            "archie-arduino-left-leg.toml",
            "archie-arduino-right-leg.toml",
        ] {
            let cfg = shipped(f);
            cfg.check().unwrap();
            assert_eq!(cfg.joint.len(), 6);
        }
        let cfg = shipped("archie-arduino-left-leg.toml");
        let knee = &cfg.joint[3].name;
        let ok = cfg
            .to_board(&cmd(knee, JointCommandT::MODE_DUTY, 0.5))
            .unwrap();
        assert_eq!(ok[0].value, 5000);
        assert!(matches!(
            cfg.to_board(&cmd(knee, JointCommandT::MODE_DUTY, 0.95)),
            Err(Reject::Limit { .. })
        ));
        assert!(matches!(
            cfg.to_board(&cmd(knee, JointCommandT::MODE_POSITION, 3.0)),
            Err(Reject::Limit { .. })
        ));
        assert!(matches!(
            cfg.to_board(&cmd(knee, JointCommandT::MODE_CURRENT, 1.0)),
            Err(Reject::Mode { .. })
        ));
        assert!(matches!(
            cfg.to_board(&cmd(knee, JointCommandT::MODE_DUTY, f64::NAN)),
            Err(Reject::Limit { .. })
        ));
        let mut twice = cmd(knee, JointCommandT::MODE_DUTY, 0.1);
        twice.names.push(knee.clone());
        twice.modes.push(JointCommandT::MODE_DUTY);
        twice.setpoints.push(-0.1);
        assert_eq!(
            cfg.to_board(&twice),
            Err(Reject::DuplicateJoint(knee.clone()))
        );
    }

    #[test]
    fn a_position_beyond_the_wires_field_is_refused_not_wrapped() {
        // A joint configured wider than the wire's ±3.2767 rad: its limits pass 3.5 rad, the
        // i16 field of 1/10000 rad cannot hold it (cast, it would wrap to -3.0536 rad).
        let mut cfg = shipped("archie-arduino-left-leg.toml");
        let j = &mut cfg.joint[0];
        (j.min_position, j.max_position) = (-4.0, 4.0);
        let name = j.name.clone();
        let ok = cfg
            .to_board(&cmd(&name, JointCommandT::MODE_POSITION, 3.2))
            .unwrap();
        assert_eq!(ok[0].value, 32_000);
        match cfg.to_board(&cmd(&name, JointCommandT::MODE_POSITION, 3.5)) {
            Err(Reject::Limit { what, .. }) => assert!(what.contains("wire"), "{what}"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_synthetic_stream_converges_to_the_known_tilt() {
        // Tilted by roll 0.3, pitch -0.2, with a gyro bias and noise, at 100 Hz for 5 s.
        let (roll, pitch) = (0.3f64, -0.2f64);
        let g = [
            -pitch.sin(),
            roll.sin() * pitch.cos(),
            roll.cos() * pitch.cos(),
        ];
        let mut att = Attitude::new(0.5);
        let mut seed = 7u32;
        let mut noise = || {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((seed >> 16) & 0x7fff) as f64 / 16_383.5 - 1.0
        };
        for _ in 0..500 {
            let a = g.map(|x| x + 0.01 * noise());
            att.update(a, [0.005, -0.004, 0.0], 0.01);
        }
        // The bias leaves a steady error of bias × tau (2.5 mrad): within 0.01 rad.
        assert!((att.rpy[0] - roll).abs() < 0.01, "{:?}", att.rpy);
        assert!((att.rpy[1] - pitch).abs() < 0.01, "{:?}", att.rpy);
        let q = att.quaternion();
        assert!((q.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-9);
        // A level, still board reads identity.
        let mut level = Attitude::new(0.5);
        level.update([0.0, 0.0, 1.0], [0.0; 3], 0.01);
        assert_eq!(level.quaternion(), [1.0, 0.0, 0.0, 0.0]);
    }
}
