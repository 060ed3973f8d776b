//! `stride-elmo-bridge`: joint trajectories from LCM to Elmo drives on CAN, joint states back.

use stride_elmo_bridge::{BridgeConfig, Cli, ElmoApp};
use stride_node::Launch;

fn main() -> std::process::ExitCode {
    stride_node::main("stride-elmo-bridge", |l: Launch<Cli, BridgeConfig>| {
        let node = l.start()?;
        let mut cfg = l.cfg;
        if let Some(bus) = l.cli.bus.clone() {
            cfg.bus = bus;
        }
        let app = ElmoApp::start(&node, cfg)?;
        node.run(app)
    })
}
