//! `stride-sim`: the simulated world on the LCM bus.

use stride_node::Launch;
use stride_sim_node::app::{Cli, SimApp};
use stride_sim_node::SimConfig;

fn main() -> std::process::ExitCode {
    stride_node::main("stride-sim", |l: Launch<Cli, SimConfig>| {
        let node = l.start()?;
        let app = SimApp::start(&node, l.cfg, &l.cli)?;
        node.run(app)
    })
}
