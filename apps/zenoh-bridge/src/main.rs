//! `stride-zenoh-bridge`: chosen LCM channels between buses that share no multicast, over
//! Zenoh.

use stride_node::Launch;
use stride_zenoh_bridge::{Bridge, BridgeConfig, Cli};

fn main() -> std::process::ExitCode {
    stride_node::main("stride-zenoh-bridge", |mut l: Launch<Cli, BridgeConfig>| {
        l.cli.quiet_zenoh();
        let node = l.start()?;
        let app = Bridge::start(&node, l.cfg, l.cli.config_file())?;
        node.run(app)
    })
}
