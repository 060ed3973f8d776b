//! `stride-dynamixel-bridge`: LCM joint commands to a chain of Dynamixel servos, joint states
//! and servo health back.

use std::process::ExitCode;

use stride_dynamixel_bridge::{app::scan, BridgeConfig, Cli, DynamixelApp};
use stride_node::Launch;

fn main() -> ExitCode {
    stride_node::main("stride-dynamixel-bridge", |l: Launch<Cli, BridgeConfig>| {
        if l.cli.scan {
            l.logging();
            scan(&l.cli, &l.cfg)?;
            return Ok(ExitCode::SUCCESS);
        }
        let node = l.start()?;
        let app = DynamixelApp::start(&node, l.cfg, &l.cli)?;
        node.run(app)
    })
}
