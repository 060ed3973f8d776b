//! `stride-joint-move`: move joints smoothly from where they are to where you say.

use stride_joint_move::{Cli, Mover};
use stride_node::{Launch, NoConfig};

fn main() -> std::process::ExitCode {
    stride_node::main("stride-joint-move", |l: Launch<Cli, NoConfig>| {
        let node = l.start()?;
        let app = Mover::start(&node, l.cli)?;
        node.run(app)
    })
}
