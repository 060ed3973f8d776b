//! `stride-fake-elmo`: fake Elmo drives on a CAN bus carried over LCM.

use stride_elmo_bridge::BridgeConfig;
use stride_fake_elmo::{Cli, Rig};
use stride_node::Launch;

fn main() -> std::process::ExitCode {
    stride_node::main("stride-fake-elmo", |l: Launch<Cli, BridgeConfig>| {
        let node = l.start()?;
        let rig = Rig::start(&node, &l.cfg, &l.cli)?;
        node.run(rig)
    })
}
