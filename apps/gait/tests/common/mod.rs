//! What the gait's tests share: Archie's shipped gait configuration, its legs and a walker
//! standing at the origin, and footsteps straight ahead.

use stride_gait::archie::ArchieGait;
use stride_gait::timeline::{Footstep, Side};
use stride_gait::walker::Walker;
use stride_gait_node::{archie_gait, GaitConfig};
use stride_kinematics::archie::ArchieConfig;

fn repo(p: &str) -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join(p)
}

/// Archie as stride-gait runs it from the shipped configuration (the robot: `legs.robot`).
pub struct Archie {
    pub cfg: GaitConfig,
    pub legs: ArchieGait,
    /// Standing with the feet at y = ±0.1 m, its counter at 0.
    pub walker: Walker,
}

pub fn archie() -> Archie {
    let cfg: GaitConfig =
        toml::from_str(&std::fs::read_to_string(repo("config/gait-archie.toml")).unwrap()).unwrap();
    let robot = ArchieConfig::load(&repo("config/robots/archie.toml")).unwrap();
    let (legs, gen) = archie_gait(&cfg, robot).unwrap();
    let walker = Walker::new(
        gen,
        cfg.walker,
        0.0,
        [0.0, 0.1, 0.0, 0.0],
        [0.0, -0.1, 0.0, 0.0],
        0,
    )
    .unwrap();
    Archie { cfg, legs, walker }
}

/// Step `n` of a walk straight ahead from the origin, `stride` m each: odd steps left.
pub fn straight(n: i64, stride: f64) -> Footstep {
    let side = if n % 2 == 1 { Side::Left } else { Side::Right };
    Footstep {
        number: n,
        side,
        place: [
            stride * n as f64,
            if side == Side::Left { 0.1 } else { -0.1 },
            0.0,
            0.0,
        ],
        swing_height: 0.0,
        duration: 0.0,
        padding: false,
    }
}
