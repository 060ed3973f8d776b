//! `stride-gait`: the walking controller on the LCM bus.

use stride_gait_node::app::{Cli, GaitApp};
use stride_gait_node::GaitConfig;
use stride_node::Launch;

fn main() -> std::process::ExitCode {
    stride_node::main("stride-gait", |l: Launch<Cli, GaitConfig>| {
        let node = l.start()?;
        let app = GaitApp::start(&node, l.cfg, l.cli.config_file())?;
        node.run(app)
    })
}
