//! What the gait's tests share: Archie's robot file, the pattern's default parameters and
//! straight walks.

#![allow(dead_code)]

use std::path::Path;

use stride_gait::archie::{ArchieGait, HeightConfig};
use stride_gait::pattern::{Generator, Kind, PatternConfig, PlacementConfig};
use stride_gait::preview::PreviewConfig;
use stride_gait::support::Sole;
use stride_gait::swing::{Place, SwingConfig};
use stride_gait::timeline::{Footstep, Side, TimingConfig};
use stride_kinematics::archie::ArchieConfig;

/// Archie's sole centre is 8 cm ahead of its ankle: the ZMP reference 3 cm ahead of the
/// ankle keeps 6 cm of sole behind it and the shanks more upright.
pub const ZMP_AHEAD: f64 = -0.05;

pub fn robot() -> ArchieConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/robots/archie.toml");
    ArchieConfig::load(&path).unwrap()
}

pub fn z_c() -> f64 {
    archie().z_c
}

pub fn config(kind: Kind) -> PatternConfig {
    let r = robot();
    PatternConfig {
        generator: kind,
        z_c: z_c(),
        g: 9.80665,
        preview: PreviewConfig::default(),
        placement: PlacementConfig::default(),
        swing: SwingConfig::default(),
        // Archie's sole centre is 8 cm ahead of its ankle: the ZMP reference 3 cm ahead of
        // the ankle keeps 6 cm of sole behind it and the shanks more upright.
        timing: TimingConfig {
            zmp_ahead: ZMP_AHEAD,
            ..TimingConfig::default()
        },
        sole: Sole {
            length: r.foot.length,
            width: r.foot.width,
        },
        min_margin: 0.01,
    }
}

pub fn generator(kind: Kind) -> Generator {
    Generator::new(config(kind)).unwrap()
}

/// Archie's gait: the whole robot's COM on the pattern, rows every 10 ms.
pub fn archie() -> ArchieGait {
    ArchieGait::new(robot(), &HeightConfig::default(), ZMP_AHEAD, 0.01, true).unwrap()
}

/// The feet standing at x = 0, 0.2 m apart: left, right.
pub fn standing() -> (Place, Place) {
    ([0.0, 0.1, 0.0, 0.0], [0.0, -0.1, 0.0, 0.0])
}

/// `n` steps straight ahead, the left foot first, numbered from `first`: each lands
/// `length` ahead of the support foot, the last beside it.
pub fn straight(n: usize, length: f64, first: i64) -> Vec<Footstep> {
    let mut x = [0.0, 0.0];
    (0..n)
        .map(|i| {
            let side = if i % 2 == 0 { Side::Left } else { Side::Right };
            let k = side.index();
            x[k] = if i + 1 == n {
                x[1 - k]
            } else {
                x[1 - k] + length
            };
            let y = if side == Side::Left { 0.1 } else { -0.1 };
            Footstep {
                number: first + i as i64,
                side,
                place: [x[k], y, 0.0, 0.0],
                swing_height: 0.0,
                duration: 0.0,
                padding: false,
            }
        })
        .collect()
}
